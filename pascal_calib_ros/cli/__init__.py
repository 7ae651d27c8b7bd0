"""The command line, ``pascal-calib``: a parser and one module per command (:mod:`.main`)."""

from .main import build_parser, main

__all__ = ["build_parser", "main"]
