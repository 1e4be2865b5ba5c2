"""The packaged scenario files: one per seed scenario A to J of the FSM planner
(``spec/fsm_planner.md``; the seed's diagram of lane-changing scenarios) and stress cases.
``library_path("a_early_lane_change")`` is a file's path, :func:`library_scenarios` all of
them in name order; ``docs/scenarios.md`` lists them with the FSM styles' outcomes.
Scenarios made for one open road (the Bosch Challenge's final placement) are in
``open_roads/``, beside them: they need their map and are not among these."""

from __future__ import annotations

from pathlib import Path

LIBRARY = Path(__file__).resolve().parent
"""The folder of the library's ``*.yaml`` files."""


def library_path(name: str) -> Path:
    """The file of library scenario ``name`` (its stem); ``KeyError`` listing the names."""
    path = LIBRARY / f"{name}.yaml"
    if not path.is_file():
        raise KeyError(f"no library scenario {name!r}; the library has "
                       f"{[p.stem for p in library_scenarios()]}")
    return path


def library_scenarios() -> list[Path]:
    """Every library scenario file, in name order."""
    return sorted(LIBRARY.glob("*.yaml"))
