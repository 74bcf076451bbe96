"""The package's version, in a module of its own: the library's modules (io, stationary,
report, export) read it from here and never import the package root."""

__version__ = "0.1.0"
