"""Output: VTU files and PVD time series (meshio), time-series tables, plain-data files.

Every file is written to a temporary name in the target directory and then
renamed, so that a run killed at any moment leaves each earlier file complete
and readable; a table's CSV file grows by appended, synced rows
(:class:`CSVLog`). :mod:`.plain` stores nested values as numpy arrays and a
JSON header (checkpoints), and reads them back strictly, without pickle.
"""

from . import plain
from .csv_log import CSVLog, read_csv
from .files import (
    PARTIAL_PREFIX,
    atomic_path,
    atomic_write,
    check_output_file,
    check_writable,
    keep_previous,
    partial_files,
    remove_partial_files,
    save_figure,
    write_text,
)
from .pvd import PVDSeries, read_pvd
from .table import History, Table
from .vtu import write_vtu

__all__ = ["PARTIAL_PREFIX", "CSVLog", "History", "PVDSeries", "Table", "atomic_path",
           "atomic_write", "check_output_file",
           "check_writable", "keep_previous", "partial_files", "plain", "read_csv", "read_pvd",
           "remove_partial_files", "save_figure", "write_text", "write_vtu"]
