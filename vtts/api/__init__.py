"""The library API of the ``vtts`` commands: one function per command, each taking a dataclass
of options checked when it is made and returning what it wrote or found.

- :func:`~vtts.api.say.say` (:class:`~vtts.api.say.SayOptions`) → :class:`~vtts.api.say.Said`
- :func:`~vtts.api.play.play` (:class:`~vtts.api.play.PlayOptions`) → :class:`~vtts.api.play.Played`
- ``render_still`` (:class:`~vtts.api.render.RenderOptions`) → :class:`~vtts.api.render.Still`
- :func:`~vtts.api.pose.pose` (:class:`~vtts.api.pose.PoseOptions`) → the ``.wrl`` written
- :func:`~vtts.api.analyze.analyze` (:class:`~vtts.api.analyze.AnalyzeOptions`) →
  :class:`~vtts.api.analyze.Analyzed`
- :func:`~vtts.api.coding.encode` (:class:`~vtts.api.coding.EncodeOptions`) →
  :class:`~vtts.api.coding.Encoded`; :func:`~vtts.api.coding.decode`
  (:class:`~vtts.api.coding.DecodeOptions`) → the decoded stream
- :func:`~vtts.api.check.check` (files) → a :class:`~vtts.api.check.Checked` each;
  :func:`~vtts.api.info.info` (a file) → :class:`~vtts.api.info.Info`;
  :func:`~vtts.api.models.models` → a :class:`~vtts.api.models.Bundled` each
- :func:`~vtts.api.speak.speak` (one clause, a model) → :class:`~vtts.api.speak.Spoken`, in
  memory: what ``vtts serve`` streams

Option pieces shared by several commands (the heads, the view, a pose, curves) are in
:mod:`vtts.api.options`; :func:`vtts.api.reporting.run_reported` tells a failure as the command
line does. Every name here is importable from ``vtts`` itself (``vtts.say``, ``vtts.SayOptions``); a
name's module is imported on first use, so ``import vtts`` stays as light as it was. The render
function is ``render_still`` because ``vtts.render`` is the renderer's package.
"""

from __future__ import annotations

import importlib

#: Public name → the module that defines it (as ``module`` or ``module:attribute``).
EXPORTS: dict[str, str] = {
    "say": "vtts.api.say",
    "SayOptions": "vtts.api.say",
    "Said": "vtts.api.say",
    "play": "vtts.api.play",
    "PlayOptions": "vtts.api.play",
    "Played": "vtts.api.play",
    "render_still": "vtts.api.render:render",
    "RenderOptions": "vtts.api.render",
    "Still": "vtts.api.render",
    "pose": "vtts.api.pose",
    "PoseOptions": "vtts.api.pose",
    "analyze": "vtts.api.analyze",
    "AnalyzeOptions": "vtts.api.analyze",
    "Analyzed": "vtts.api.analyze",
    "encode": "vtts.api.coding",
    "EncodeOptions": "vtts.api.coding",
    "Encoded": "vtts.api.coding",
    "decode": "vtts.api.coding",
    "DecodeOptions": "vtts.api.coding",
    "read_stream": "vtts.api.coding",
    "check": "vtts.api.check",
    "check_file": "vtts.api.check",
    "Checked": "vtts.api.check",
    "info": "vtts.api.info",
    "Info": "vtts.api.info",
    "models": "vtts.api.models",
    "Bundled": "vtts.api.models",
    "voices": "vtts.speech.tts",
    "speak": "vtts.api.speak",
    "Spoken": "vtts.api.speak",
}


def export(name: str):
    """The object :data:`EXPORTS` names ``name``, its module imported now."""
    where = EXPORTS[name]
    module, _, attribute = where.partition(":")
    return getattr(importlib.import_module(module), attribute or name)


def __getattr__(name: str):
    if name in EXPORTS:
        return export(name)
    raise AttributeError(f"module 'vtts.api' has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted([*globals(), *EXPORTS])


__all__ = sorted(EXPORTS)
