"""``python -m vtts.cli``: the ``vtts`` command."""

from vtts.cli import run

if __name__ == "__main__":  # not when a batch's worker process starts (vtts.batch.pool)
    run()
