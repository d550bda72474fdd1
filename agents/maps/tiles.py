"""Copy-on-write map tiles shared by identity between the UAVs' tiled maps (issue 36, T8).

Storage only: every map keeps reading exactly its own cells. Receivers that hold the same tile
*object* and stamp the same scan onto it would each compute the same new tile; instead the first
computes it and the others take that very result (:meth:`TileShare.stamp`): one physical stamp
and one tile in memory for all of them. Maps that start a tile with the same scan (a tile never
written is one shared all-``-inf`` object) and go on hearing the same scans in the same order
keep sharing it; a map that stamps a scan the others do not gets a tile of its own.

The rules, which keep every map's cells those of a map of its own:

- A tiled map *owns* some of its tiles (:attr:`UncertaintyMap._own`): those no other map and no
  memo entry holds. It writes an owned tile in place, as an ordinary map does.
- Any other tile of it may be shared: read-only (numpy's ``writeable`` flag, so a write that
  forgot the rule raises instead of changing another map's cells). A stamp on it goes through the
  memo here; any other write (``scan_disk``, ``cover``, ``stamp_once``, ``merge``) copies it
  first into a tile the map owns (:meth:`UncertaintyMap._writable`).
- The memo maps ``(tile key, piece start, the tile object, the piece's values object)`` to the
  resulting tile (it holds the tile and the values, so their ids stay theirs). A result is
  ``maximum(tile, values)`` on the piece: exactly what the stamp would have written in place.
- :meth:`TileShare.flush` (every tick, :meth:`Grid.new_tick`; and whenever the memo grows past
  :data:`MEMO_MAX`) forgets the memo; a result that no other map took and its maker still holds
  is then owned by its maker again (written in place from then on).

What it saves was measured with ``/work/notes/out-tiles-measure.py`` (bench-100-greedy 300 s: 30%
of tile-piece stamps and 22% of tiles; bench-1000-greedy 20 s: 65% and 59%).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from agents.maps.umap import UncertaintyMap

# Memo entries after which the memo is flushed even within a tick (it pins two tiles each: about
# 2 GB of 16 KB tiles at most; a tick of bench-1000 makes about 6 000).
MEMO_MAX = 1 << 16

# A memo entry: the tile stamped, the values stamped on it, the result, the map that made it,
# the tile key, and whether another map took the result.
_Entry = list[object]


class TileShare:
    """The per-tick memo of stamps on shared tiles (one per grid: :meth:`Grid.tile_share`)."""

    __slots__ = ("memo", "empty", "stamps", "made")

    def __init__(self) -> None:
        self.memo: dict[tuple[int, int, int, int], _Entry] = {}
        # The never-written tile of each flat size (read-only, -inf): what a map without the tile
        # stamps onto, so maps starting a tile with the same scan share it from the start.
        self.empty: dict[int, np.ndarray] = {}
        self.stamps = 0  # pieces stamped through the memo (for studies and tests)
        self.made = 0  # of which computed (memo misses)

    def empty_tile(self, size: int) -> np.ndarray:
        tile = self.empty.get(size)
        if tile is None:
            tile = self.empty[size] = np.full(size, -np.inf, dtype=np.float32)
            tile.flags.writeable = False
        return tile

    def stamp(self, umap: UncertaintyMap, key: int, tile: np.ndarray | None, start: int, stop: int,
              values: np.ndarray) -> None:
        """``umap``'s tile ``key`` (``tile``: its current, possibly shared object; None: never
        written) becomes ``maximum`` of it and ``values`` on ``[start:stop]``: the memoised result
        if another map made it from the same object, else a new read-only tile."""
        if tile is None:
            tile = self.empty_tile(umap.tile_shape[0] * umap.tile_shape[1])
        mk = (key, start, id(tile), id(values))
        self.stamps += 1
        entry = self.memo.get(mk)
        if entry is not None:
            entry[5] = True
            umap._tiles[key] = entry[2]  # type: ignore[assignment]
            return
        new = tile.copy()
        view = new[start:stop]
        np.maximum(view, values, out=view)
        new.flags.writeable = False
        umap._tiles[key] = new
        self.made += 1
        memo = self.memo
        if len(memo) >= MEMO_MAX:
            self.flush()
        memo[mk] = [tile, values, new, umap, key, False]

    def flush(self) -> None:
        """Forget the memo; give each result no other map took back to its maker (owned: written
        in place) if the maker still holds it."""
        memo, self.memo = self.memo, {}
        for _tile, _values, new, umap, key, taken in memo.values():
            if not taken and umap._tiles.get(key) is new:  # type: ignore[attr-defined]
                new.flags.writeable = True  # type: ignore[attr-defined]
                umap._own.add(key)  # type: ignore[attr-defined]
