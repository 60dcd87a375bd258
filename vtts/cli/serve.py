"""``vtts serve``: a live talking head in the browser (:mod:`vtts.serve`)."""

from __future__ import annotations

import argparse

from vtts.cli.options import seed_type
from vtts.messages import echo


def add_parser(sub) -> None:
    sv = sub.add_parser(
        "serve",
        help="serve a live talking head: a page and a WebSocket that speak text as it comes",
        description="Serve the page and one WebSocket session per client (docs/serve.md): text "
        "in, whole or a few words at a time, and each clause's speech and face out as soon as "
        "it is synthesized. Bound to localhost unless --host says otherwise.",
    )
    sv.add_argument("--host", default="127.0.0.1", help="address to listen on (default 127.0.0.1)")
    sv.add_argument("--port", type=int, default=8080, help="port (default 8080; 0: any free one)")
    sv.add_argument(
        "--model",
        action="append",
        help="bundled model name or .wrl path a session may open (repeat for several; "
        "default cybatt); the first is a session's default",
    )
    sv.add_argument(
        "--engine", default="espeak", help="speech synthesizer of the sessions (default espeak)"
    )
    sv.add_argument("--voice", help="its voice (default: the engine's)")
    sv.add_argument("--fps", type=float, default=30.0, help="face frames per second (default 30)")
    sv.add_argument(
        "--seed", type=seed_type, default=0, help="seed of the first session's behaviour"
    )
    sv.add_argument(
        "--replicas",
        type=int,
        metavar="N",
        help="serve on Ray Serve: N servers (replicas) behind Ray's HTTP proxy, on a Ray started "
        "here or joined at --ray-address (needs the extra vtts[rayserve]; docs/serve.md)",
    )
    sv.add_argument(
        "--ray-address", metavar="ADDR", help="with --replicas: the Ray cluster to join"
    )
    sv.set_defaults(func=cmd_serve)


def cmd_serve(args: argparse.Namespace) -> int:
    """Serve until interrupted (Ctrl-C, SIGTERM)."""
    from vtts.api.options import check_choice, check_number, check_seed
    from vtts.api.say import ENGINES
    from vtts.errors import ServeError
    from vtts.serve.server import ServerOptions, run_server

    check_choice(args.engine, "--engine", ENGINES)
    check_number(args.fps, "--fps", 0, 240)
    check_seed(args.seed)
    options = ServerOptions(engine=args.engine, voice=args.voice, fps=args.fps, seed=args.seed)
    if args.ray_address is not None and args.replicas is None:
        raise ServeError("--ray-address goes with --replicas N (serving on Ray Serve)")
    try:
        if args.replicas is not None:
            check_number(args.replicas, "--replicas", 0, 256, ServeError)
            from vtts.face import load_model

            for name in args.model or ["cybatt"]:  # a bad model: an error here, before Ray
                load_model(name)
            from vtts.serve.ray_serve import run_on_ray

            run_on_ray(args.model or ["cybatt"], replicas=args.replicas, host=args.host,
                       port=args.port, options=options, address=args.ray_address,
                       announce=echo)  # fmt: skip
        else:
            run_server(args.model or ["cybatt"], host=args.host, port=args.port, options=options,
                       announce=echo)  # fmt: skip
    except KeyboardInterrupt:
        echo("vtts serve: stopped")
    return 0
