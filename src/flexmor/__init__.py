"""flexmor: model order reduction of elastic bodies for multibody simulation."""

__version__ = "0.1.0"
