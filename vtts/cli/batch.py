"""``vtts batch JOBS.jsonl --out DIR``: many say/play/render jobs on worker processes of this
machine, or on Ray."""

from __future__ import annotations

import argparse

from vtts.messages import echo, print_error


def add_parser(sub) -> None:
    ba = sub.add_parser("batch", help="run many say/play/render jobs on worker processes or Ray")
    ba.add_argument("jobs", metavar="JOBS.jsonl", help="one job per line (docs/batch.md)")
    ba.add_argument("--out", required=True, metavar="DIR", help="the outputs' folder")
    ba.add_argument("--workers", type=int, metavar="N", help="workers (default: one per CPU)")
    ba.add_argument(
        "--address", help="an existing Ray cluster (default: worker processes of this machine)"
    )
    ba.add_argument(
        "--ray", action="store_true", help="run on a local Ray instance (as a cluster would)"
    )
    ba.add_argument("--dry-run", action="store_true", help="check every line, render nothing")
    ba.set_defaults(func=cmd_batch)


def cmd_batch(args: argparse.Namespace) -> int:
    """Run the jobs (:func:`vtts.batch.run`), or with --dry-run only check every line
    (:func:`vtts.batch.dry_run`)."""
    from vtts.batch import dry_run, run

    if args.dry_run:
        checked = dry_run(args.jobs, args.out)
        for e in checked.errors:
            print_error(e)
        n = len(checked.jobs)
        echo(f"{args.jobs}: {n} valid job{'s' if n != 1 else ''}, {len(checked.errors)} bad")
        return 1 if checked.errors else 0
    report = run(args.jobs, args.out, args.workers, args.address, show_progress=True, ray=args.ray)
    echo(f"batch: {report.summary()}")
    return 0 if report.ok else 1
