"""The ``adi`` command (Animation Definition Interface): building and inspecting ADTs.

The sub-commands arrive with the personalized models (issue 3); until then ``adi`` only reports
its version.
"""

from __future__ import annotations

import argparse
import sys

from vtts import __version__


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(
        prog="adi", description="Build and inspect Animation Definition Tables."
    )
    p.add_argument("--version", action="version", version=f"adi {__version__}")
    p.parse_args(argv)
    p.print_help()
    return 0


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
