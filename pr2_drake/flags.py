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


def yaml_file(text: str) -> str:
    """A YAML file (as given, or under the data root) that parses; returned as given."""
    import yaml

    from pr2_drake.paths import resolve_user_path

    try:
        path = resolve_user_path(text, "YAML")
        with open(path) as f:
            yaml.safe_load(f)
    except (FileNotFoundError, IsADirectoryError):
        raise argparse.ArgumentTypeError(f"file not found: {text}") from None
    except (OSError, UnicodeDecodeError) as e:
        raise argparse.ArgumentTypeError(f"cannot read {text}: {e}") from None
    except yaml.YAMLError as e:
        raise argparse.ArgumentTypeError(f"{text} is not valid YAML: "
                                         f"{' '.join(str(e).split())}") from None
    return text
