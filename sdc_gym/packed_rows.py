"""Named rows of packed blocks that survive ``copy.deepcopy`` and pickling.

The batch state keeps many per-env quantities as rows of a few packed 2-D or 3-D arrays
(the compiled kernels take a handful of blocks, whatever the number of fields), and each
row is also an attribute: ``state.speed`` is ``state.car_floats[CAR_FLOATS.index("speed")]``,
a view. ``copy.deepcopy`` and ``pickle`` copy every array on its own, so a plain copy holds
blocks and rows that no longer share memory: the kernels then write the copy's blocks
while its attributes keep the values of the moment of the copy, and a copied env drives on
with frozen metrics and traffic. Lookahead planners (highway-env's MCTS agents, a
clairvoyant rollout) rely on ``copy.deepcopy(env)`` being an independent env that goes on
exactly as the original would.

A class with such rows derives from :class:`PackedRows` and names its blocks in
:attr:`~PackedRows.PACKED_ROWS`. Its deep copy copies each block once and registers each
of the copy's rows in the memo under the original row's id (so anything else in the copied
graph that refers to a row gets the copy's view, not a detached array); its pickled state
leaves the rows out and binds them again on loading.
"""

from __future__ import annotations

import copy
from collections.abc import Iterator, Sequence
from typing import Any, ClassVar


class PackedRows:
    """Attributes that are the rows of packed blocks, kept so by copies and pickles."""

    PACKED_ROWS: ClassVar[tuple[tuple[str, str], ...]] = ()
    """Pairs of (block attribute, class attribute holding its row names in row order)."""

    def _layout(self) -> Iterator[tuple[str, Sequence[str]]]:
        for block_name, names_name in self.PACKED_ROWS:
            yield block_name, getattr(self, names_name)

    def _bind_rows(self) -> None:
        """Make each named row a view of its block (after ``__init__`` or a load)."""
        for block_name, names in self._layout():
            block = getattr(self, block_name)
            for row, name in enumerate(names):
                setattr(self, name, block[row])

    def __deepcopy__(self, memo: dict[int, Any]) -> Any:
        cls = type(self)
        duplicate = cls.__new__(cls)
        memo[id(self)] = duplicate
        for block_name, names in self._layout():
            block_copy = copy.deepcopy(getattr(self, block_name), memo)
            for row, name in enumerate(names):
                memo[id(getattr(self, name))] = block_copy[row]
        for name, value in vars(self).items():
            setattr(duplicate, name, copy.deepcopy(value, memo))
        return duplicate

    def __getstate__(self) -> dict[str, Any]:
        rows = {name for _, names in self._layout() for name in names}
        return {name: value for name, value in vars(self).items() if name not in rows}

    def __setstate__(self, state: dict[str, Any]) -> None:
        vars(self).update(state)
        self._bind_rows()
