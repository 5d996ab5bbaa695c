"""SID, the Standard Input Data of a flexible body (Wallrapp 1994): the exporter (:mod:`.sid`),
the reader (:mod:`.sid_reader`) and the data types (:mod:`.sid_types`)."""

from .sid import sid_from_reduced, write_sid
from .sid_reader import read_sid
from .sid_types import M1_ORDERS, SIDFile, SIDNode, Taylor

__all__ = ["M1_ORDERS", "SIDFile", "SIDNode", "Taylor", "read_sid", "sid_from_reduced", "write_sid"]
