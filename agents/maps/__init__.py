"""A UAV's map: the grid geometry and shared scan disks (:mod:`.grid`), the uncertainty map as a
max-CRDT of last-seen times (:mod:`.umap`), storage shared by maps that agree
(:mod:`.mapgroup`), and the log of every scan a UAV knows, for anti-entropy (:mod:`.scanlog`)."""

from agents.maps.grid import Disk, Grid
from agents.maps.mapgroup import GroupMap, MapGroup
from agents.maps.scanlog import ScanLog
from agents.maps.umap import UncertaintyMap

__all__ = ["Disk", "Grid", "GroupMap", "MapGroup", "ScanLog", "UncertaintyMap"]
