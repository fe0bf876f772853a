"""The package's version (also ``hierplan_opt.__version__`` and ``hierplan --version``)."""

__version__ = "0.1.0"
