"""Output: VTU files and PVD time series (meshio), time-series tables, all written atomically.

Every file is written to a temporary name in the target directory and then
renamed, so that a run killed at any moment leaves each earlier file complete
and readable.
"""

from .files import atomic_write, check_writable
from .pvd import PVDSeries, read_pvd
from .table import History, Table
from .vtu import write_vtu

__all__ = ["History", "PVDSeries", "Table", "atomic_write", "check_writable", "read_pvd",
           "write_vtu"]
