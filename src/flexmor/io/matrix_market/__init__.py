"""Matrix Market: mass/stiffness pairs to read as an FE model (:mod:`.matrix_market`) and
reduced bodies to export as such a set (:mod:`.matrix_market_export`)."""

from .matrix_market import find_siblings, read_matrix_market
from .matrix_market_export import write_matrix_market

__all__ = ["find_siblings", "read_matrix_market", "write_matrix_market"]
