"""Copy-on-write map tiles shared by identity between the UAVs' tiled maps (issue 36, T8).

Storage only: every map keeps reading exactly its own cells. Receivers that hold the same tile
*object* and stamp the same scan onto it would each compute the same new tile; instead the first
computes it and the others take that very result (:meth:`TileShare.stamp`): one physical stamp
and one tile in memory for all of them. Maps that start a tile with the same scan (a tile never
written is one shared all-``-inf`` object) and go on hearing the same scans in the same order
keep sharing it; a map that stamps a scan the others do not gets a tile of its own.

The rules, which keep every map's cells those of a map of its own:

- A tiled map *owns* some of its tiles (``UncertaintyMap._own``): those no other map and no
  memo entry holds. It writes an owned tile in place, as an ordinary map does.
- Any other tile of it may be shared, and is never written. A stamp on it goes through the memo
  here; any other write (``scan_disk``, ``cover``, ``stamp_once``, ``merge``) copies it first
  into a tile the map owns (``UncertaintyMap._writable``). (Shared tiles are not marked read-only
  with numpy's flag: setting it costs about 0.9 us, as much as a third of a stamp;
  ``tests/test_tiles.py`` checks that no map's cells change by another's writes.)
- The memo maps ``(tile key, piece start, the tile object, the piece's values object)`` to the
  resulting tile (it holds the tile and the values, so their ids stay theirs). A result is
  ``maximum(tile, values)`` on the piece: exactly what the stamp would have written in place.
- :meth:`TileShare.flush` (every tick, :meth:`Grid.new_tick`; and whenever the memo grows past
  :data:`MEMO_MAX`) forgets the memo; a result that no other map took and its maker still holds
  is then owned by its maker again (written in place from then on).

Measured (issue 36, T8): on bench-100-greedy at 300 s it saves 30% of the tile-piece stamps and
22% of the tiles held, on bench-1000-greedy at 20 s 65% and 59%. It saves memory (peak RSS of
bench-1000-dacmp over 200 s 2256 -> 1993 MB), not CPU: a memo hit costs about half a stamp in
place, a miss on a shared tile (a 16 KB copy, then the stamp) two to three stamps, and on the
bench cases the copies eat what the hits save.
"""

from __future__ import annotations

from typing import Any

import numpy as np

# Memo entries after which the memo is flushed even within a tick (it pins two tiles each: about
# 2 GB of 16 KB tiles at most; a tick of bench-1000-greedy makes about 2 600).
MEMO_MAX = 1 << 16

Tiles = dict[int, np.ndarray]  # a tiled map's storage: tile key -> flat cells
# A memo entry: the tile stamped, the values stamped on it, the result, the tiles, owned keys and
# tile key of the map that made it, and whether another map took the result (a list: the flag is
# set in place).
_Entry = list[Any]


class TileShare:
    """The per-tick memo of stamps on shared tiles (one per grid: :meth:`Grid.tile_share`)."""

    __slots__ = ("memo", "empty", "stamps", "made")

    def __init__(self) -> None:
        self.memo: dict[tuple[int, int, int, int], _Entry] = {}
        # The never-written tile of each flat size (-inf, never written): what a map without the tile
        # stamps onto, so maps starting a tile with the same scan share it from the start.
        self.empty: dict[int, np.ndarray] = {}
        self.stamps = 0  # pieces stamped through the memo (for studies and tests)
        self.made = 0  # of which computed (memo misses)

    def empty_tile(self, size: int) -> np.ndarray:
        tile = self.empty.get(size)
        if tile is None:
            tile = self.empty[size] = np.full(size, -np.inf, dtype=np.float32)
            tile.flags.writeable = False  # (once per size)
        return tile

    def stamp(self, tiles: Tiles, own: set[int], key: int, size: int, start: int, values: np.ndarray) -> None:
        """A map's tile ``key`` (``tiles[key]``: a tile ``own`` does not hold, possibly shared;
        absent: never written, ``size`` cells of ``-inf``) becomes the ``maximum`` of it and
        ``values`` on ``[start:start + len(values)]``: the memoised result if another map made it
        from the same object, else a new tile (owned by ``own``'s map again after the
        next :meth:`flush` if no other map took it)."""
        tile = tiles.get(key)
        if tile is None:
            tile = self.empty.get(size)
            if tile is None:
                tile = self.empty_tile(size)
        mk = (key, start, id(tile), id(values))
        self.stamps += 1
        memo = self.memo
        entry = memo.get(mk)
        if entry is not None:
            entry[6] = True
            tiles[key] = entry[2]
            return
        new = tile.copy()
        view = new[start : start + len(values)]
        np.maximum(view, values, out=view)
        tiles[key] = new
        self.made += 1
        if len(memo) >= MEMO_MAX:
            self.flush()
            memo = self.memo
        memo[mk] = [tile, values, new, tiles, own, key, False]

    def flush(self) -> None:
        """Forget the memo; give each result no other map took back to its maker (owned: written
        in place) if the maker still holds it."""
        memo, self.memo = self.memo, {}
        for _tile, _values, new, tiles, own, key, taken in memo.values():
            if not taken and tiles.get(key) is new:
                own.add(key)
