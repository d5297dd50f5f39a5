"""The version of tumble: the one place it is written (pyproject.toml reads it from here when the package is built).

A literal, not ``importlib.metadata.version("tumble")``: reading the installed metadata costs 20 ms at every start of
the command line (``tumble --help`` included), and a source tree that was not installed knows its version too."""

__version__ = "0.1.0"
