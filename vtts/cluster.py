"""Ray, for the commands that spread work over it (``vtts batch --ray``, ``vtts serve
--replicas``): imported quietly, a local instance started or a cluster joined, with the
command's own signal handlers kept.

Each caller gives the error type its command raises (:class:`~vtts.errors.BatchError`,
:class:`~vtts.errors.ServeError`) and the option that names the cluster's address.
"""

from __future__ import annotations

import logging
import os
import signal
import socket
import threading

from vtts.errors import VttsError

__all__ = ["CONNECT_TIMEOUT_S", "check_reachable", "import_ray", "start_ray"]

#: How long an address has to answer, in seconds: Ray's own connection retries for minutes.
CONNECT_TIMEOUT_S = 10.0


def import_ray(error: type[VttsError], needs: str):
    """Ray, imported quietly (no usage statistics sent); without it ``error`` saying ``needs``
    (what to install)."""
    os.environ.setdefault("RAY_USAGE_STATS_ENABLED", "0")
    try:
        import ray
    except ImportError:
        raise error(needs) from None
    return ray


def start_ray(ray, *, cpus: int | None, address: str | None, temp_dir: str | None,
              error: type[VttsError], option: str = "--address") -> None:  # fmt: skip
    """Start a local Ray instance of ``cpus`` CPUs (this machine's when None) on the loopback
    interface, its sockets and logs under ``temp_dir``; or join the cluster at ``address``
    (checked first: :func:`check_reachable`). Ray's ``init`` makes SIGTERM exit at once (with
    its stack dumps): the command's own handlers of SIGINT, SIGTERM and SIGHUP are put back, so
    that a signal ends the command as Ctrl-C does."""
    options = dict(
        include_dashboard=False,
        logging_level=logging.ERROR,
        log_to_driver=False,
        configure_logging=True,
    )
    if address:
        check_reachable(address, error, option)
    kept = {}
    if threading.current_thread() is threading.main_thread():
        kept = {s: signal.getsignal(s) for s in (signal.SIGINT, signal.SIGTERM, signal.SIGHUP)}
    try:
        if address:
            ray.init(address=address, **options)
        else:
            # not the /tmp/ray that another user's Ray may own
            local = cpus or os.cpu_count() or 1
            ray.init(num_cpus=local, _node_ip_address="127.0.0.1", _temp_dir=temp_dir, **options)
    except Exception as e:
        where = f"the Ray cluster at {address}" if address else "a local Ray instance"
        raise error(f"cannot start {where}: {e}") from None
    finally:
        for sig, handler in kept.items():
            if handler is not None:
                signal.signal(sig, handler)


def check_reachable(address: str, error: type[VttsError], option: str = "--address") -> None:
    """Fail at once, naming ``address``, when nothing answers there within
    :data:`CONNECT_TIMEOUT_S`: Ray retries such an address for minutes, deaf to Ctrl-C, and
    its warning names another address."""
    if address == "auto":  # Ray finds the cluster itself (RAY_ADDRESS, or the local one)
        return
    host, sep, port = address.removeprefix("ray://").rpartition(":")
    host = host.strip("[]")  # an IPv6 address: [::1]:6379
    if not (sep and host and port.isdigit() and 0 < int(port) < 65536):
        raise error(f"{option} is HOST:PORT, ray://HOST:PORT or auto, got {address!r}")
    try:
        socket.create_connection((host, int(port)), timeout=CONNECT_TIMEOUT_S).close()
    except OSError as e:
        reason = (
            f"no answer within {CONNECT_TIMEOUT_S:g} s"
            if isinstance(e, TimeoutError)
            else (e.strerror or str(e)).lower()
        )
        raise error(f"cannot reach the Ray cluster at {address}: {reason}") from None
