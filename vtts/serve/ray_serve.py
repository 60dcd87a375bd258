"""``vtts serve --replicas N``: the server on Ray Serve, N replicas behind Ray's HTTP proxy.

Sessions share nothing but read-only heads, so a server scales out by running several: each
replica is a whole :class:`~vtts.serve.server.Server` (its heads, its synthesis pool) serving the
same routes through :func:`vtts.serve.asgi.asgi_app`; Ray's proxy passes each WebSocket to one
replica for the socket's life (the ``opened`` message's ``server`` names which). A replica that
dies ends its sessions' sockets (the Python client raises :class:`~vtts.errors.ServeError`, the
page gives an ``error`` event with ``code: "closed"``); Ray starts another in its place and the
other replicas' sessions go on.

- :func:`run_on_ray` — what ``vtts serve --replicas N [--ray-address ADDR]`` runs: Ray started
  on this machine (or joined at ``address``), Serve's proxy on ``host:port``, the deployment run
  until interrupted;
- :func:`deployment` — the bound application, for :func:`ray.serve.run` in a program;
- :func:`build` — an application builder for Ray's own tools: ``serve run
  vtts.serve.ray_serve:build models=cybatt,lotta replicas=4`` or a ``serve deploy`` config's
  ``import_path`` (``docs/serve.md``).

Needs the extra ``vtts[rayserve]`` (``ray[serve]``).
"""

from __future__ import annotations

import math
import os
import re
import time
from collections.abc import Callable

from vtts.errors import ServeError
from vtts.limits import MAX_SERVE_SESSIONS
from vtts.serve.server import ServerOptions

os.environ.setdefault("RAY_USAGE_STATS_ENABLED", "0")  # as vtts.cluster imports Ray
try:
    from ray import serve
except ImportError:  # pragma: no cover - the message is the test
    raise ServeError(
        "serving on Ray Serve needs the extra vtts[rayserve] (ray[serve]): "
        "pip install 'vtts[rayserve]'"
    ) from None

from vtts.serve.asgi import asgi_app

__all__ = ["APP_NAME", "VttsServer", "build", "deployment", "run_on_ray"]

#: The Serve application's name on the cluster.
APP_NAME = "vtts"


@serve.deployment(max_ongoing_requests=MAX_SERVE_SESSIONS, ray_actor_options={"num_cpus": 1})
@serve.ingress()
class VttsServer:
    """One replica: a :class:`~vtts.serve.server.Server` of ``models`` (warmed up before its
    first session) serving :func:`~vtts.serve.asgi.asgi_app`'s routes. Each WebSocket session is
    one of the replica's ongoing requests, at most :data:`~vtts.limits.MAX_SERVE_SESSIONS`."""

    def __init__(self, models: list[str], options: ServerOptions | None = None) -> None:
        from vtts.serve.server import Server, load_heads, warm_up

        options = options or ServerOptions()
        self.server = Server(load_heads(models, options.fps), options)
        warm_up(self.server)

    def __serve_build_asgi_app__(self):
        return asgi_app(self.server)


def deployment(models: list[str], *, replicas: int = 2, options: ServerOptions | None = None,
               replica_cpus: float = 1.0):  # fmt: skip
    """The Serve application: ``replicas`` replicas of :class:`VttsServer` serving ``models``
    (names or ``.wrl`` files, loaded by each replica), each reserving ``replica_cpus`` of Ray's
    CPUs."""
    if not isinstance(replicas, int) or isinstance(replicas, bool) or not 1 <= replicas <= 256:
        raise ServeError(f"--replicas must be a whole number 1 to 256, got {replicas!r}")
    if not (math.isfinite(replica_cpus) and 0 <= replica_cpus <= 64):
        raise ServeError(f"replica_cpus must be within 0 to 64, got {replica_cpus!r}")
    return VttsServer.options(
        num_replicas=replicas, ray_actor_options={"num_cpus": replica_cpus}
    ).bind(list(models), options or ServerOptions())


def build(args: dict) -> object:
    """An application builder for ``serve run``/``serve deploy``: ``models`` (comma-separated,
    default cybatt), ``replicas`` (default 2), ``engine``, ``voice``, ``fps``, ``seed``."""
    try:
        models = [m for m in str(args.get("models", "cybatt")).split(",") if m]
        replicas = int(args.get("replicas", 2))
        options = ServerOptions(
            engine=str(args.get("engine", "espeak")),
            voice=args.get("voice"),
            fps=float(args.get("fps", 30.0)),
            seed=int(args.get("seed", 0)),
        )
    except (TypeError, ValueError) as e:
        raise ServeError(f"vtts.serve.ray_serve:build: a bad argument: {e}") from None
    return deployment(models, replicas=replicas, options=options)


def run_on_ray(models: list[str], *, replicas: int = 2, host: str = "127.0.0.1",
               port: int = 8080, options: ServerOptions | None = None,
               address: str | None = None, announce: Callable[[str], object] = print,
               wait: Callable[[], object] | None = None) -> None:  # fmt: skip
    """Serve ``models`` on Ray Serve: Ray started here (as many CPUs as this machine's cores or
    ``replicas``, whichever is more) or joined at ``address``, the proxy on ``host:port``,
    ``replicas`` replicas; until interrupted (or ``wait`` returns), then the application and
    Serve are shut down (a local Ray with them)."""
    import shutil
    import tempfile

    from vtts.cluster import import_ray, start_ray

    if not 1 <= port <= 65535:
        raise ServeError(f"--port must be within 1 to 65535 on Ray Serve, got {port}")
    app = deployment(models, replicas=replicas, options=options)
    ray = import_ray(ServeError, "serving on Ray Serve needs the extra vtts[rayserve]")
    started_here = not ray.is_initialized()
    # short: Ray's Unix sockets live in it (a socket path has at most 107 characters)
    temp_dir = tempfile.mkdtemp(prefix="vtts-ray-", dir="/tmp" if os.path.isdir("/tmp") else None)
    if started_here:
        try:
            cpus = max(len(os.sched_getaffinity(0)), replicas)
            start_ray(ray, cpus=cpus, address=address, temp_dir=temp_dir, error=ServeError,
                      option="--ray-address")  # fmt: skip
        except BaseException:
            shutil.rmtree(temp_dir, ignore_errors=True)
            raise
    try:
        try:
            serve.start(http_options={"host": host, "port": port})
            serve.run(app, name=APP_NAME, route_prefix="/")
        except Exception as e:  # Ray's own errors (an actor that died, a port taken, a timeout)
            cause = getattr(e, "cause", None) or e  # a task's error carries the one it raised
            lines = re.sub(r"\x1b\[[0-9;]*m", "", str(cause)).strip().splitlines()
            raise ServeError(
                f"Ray Serve did not start on {host}:{port}: {type(cause).__name__}: "
                f"{lines[-1] if lines else 'no message'}"
            ) from None
        announce(
            f"vtts serve: http://{host if ':' not in host else f'[{host}]'}:{port}/ "
            f"({', '.join(models)}; {replicas} Ray Serve replicas); Ctrl-C ends it"
        )
        if wait is not None:
            wait()
        else:
            while True:
                time.sleep(3600)
    finally:
        try:
            serve.shutdown()
        finally:
            if started_here:
                ray.shutdown()
            shutil.rmtree(temp_dir, ignore_errors=True)
