"""``python -m sdc_training`` and the ``sdc-train`` command: ``python train.py`` installed
(the same arguments; ``train.py --help``)."""

from __future__ import annotations

import sys


def main(argv: list[str] | None = None) -> int:
    """Run train.py's command line; 0 once the model is saved (errors exit with their
    message, as train.py's)."""
    from sdc_gym_cli import train  # train.py, installed under this name (pyproject)

    train.main(argv)
    return 0


if __name__ == "__main__":
    sys.exit(main())
