"""Types of command-line flags that refuse what cannot be meant: ``type=positive_float`` makes
``--seconds nan``, ``-1``, ``0`` and ``inf`` an argparse error naming the flag (exit status 2)."""

from __future__ import annotations

import argparse
import math


def positive_float(text: str) -> float:
    """A finite number > 0."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None
    if not math.isfinite(value) or value <= 0:
        raise argparse.ArgumentTypeError(f"must be a positive finite number, got {text!r}")
    return value


def positive_int(text: str) -> int:
    """An integer > 0."""
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a whole number, got {text!r}") from None
    if value <= 0:
        raise argparse.ArgumentTypeError(f"must be a positive whole number, got {text!r}")
    return value


class OneLineErrors(argparse.ArgumentParser):
    """An argument parser whose errors are one line, ``PROG: error: ...`` with the top-level
    program's name, and exit status 2 (subcommand parsers made from it are alike)."""

    def error(self, message: str):
        prog = self.prog.split()[0] if self.prog else "error"
        self.exit(2, f"{prog}: error: {' '.join(message.split())}\n")

