"""``python -m sdc_evaluation`` and the ``sdc-evaluate`` command: ``python evaluate.py``
installed (the same arguments and exit status; ``evaluate.py --help``)."""

from __future__ import annotations

import sys


def main(argv: list[str] | None = None) -> int:
    """Run evaluate.py's command line; the exit status (1 when an episode failed)."""
    from sdc_gym_cli import evaluate  # evaluate.py, installed under this name (pyproject)

    return evaluate.cli(argv)


if __name__ == "__main__":
    sys.exit(main())
