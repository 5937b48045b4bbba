"""The package version: a leaf module, so that whatever records it (checkpoints, results files) need
not import the package's top level."""

__version__ = "0.1.0"
