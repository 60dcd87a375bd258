"""``vtts serve``: a live talking head: text in, as a language model writes it; each clause's
speech and face out, streamed over a WebSocket to a page in the browser or to
:class:`~vtts.serve.client.Client` (``docs/serve.md``).

- :class:`~vtts.serve.server.Server` (and :func:`~vtts.serve.server.run_server`, the command);
- :mod:`vtts.serve.protocol`, the messages, version :data:`~vtts.serve.protocol.VERSION`;
- :class:`~vtts.serve.client.Client`, the Python client;
- :mod:`vtts.serve.clauses`, text cut into clauses; :mod:`vtts.serve.heads`, what the page is
  given of a model.

Imported on first use, like :mod:`vtts.api`: ``import vtts.serve`` imports no aiohttp.
"""

from __future__ import annotations

import importlib

EXPORTS = {
    "Client": "vtts.serve.client",
    "Heard": "vtts.serve.client",
    "Server": "vtts.serve.server",
    "ServerOptions": "vtts.serve.server",
    "run_server": "vtts.serve.server",
    "load_heads": "vtts.serve.server",
    "VERSION": "vtts.serve.protocol",
}


def __getattr__(name: str):
    if name in EXPORTS:
        return getattr(importlib.import_module(EXPORTS[name]), name)
    raise AttributeError(f"module 'vtts.serve' has no attribute {name!r}")


__all__ = sorted(EXPORTS)
