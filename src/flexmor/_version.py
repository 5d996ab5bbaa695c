"""The version of flexmor (a leaf module: imported by the package and by what records the version)."""

__version__ = "0.1.0"
