"""Where the project's data lives: models/, tasks/, params/, diagrams/ and scenarios/.

In a source checkout (editable install) these are the top-level folders of the repository; in an
installed wheel they ship inside the package under ``pr2_drake/share/``. Every loader asks this
module, so both layouts work without configuration.
"""

from __future__ import annotations

from pathlib import Path

_PACKAGE_DIR = Path(__file__).resolve().parent
_DATA_DIRS = ("models", "tasks", "params", "diagrams", "scenarios")


def data_root() -> Path:
    """The folder that holds models/, tasks/, params/, diagrams/ and scenarios/."""
    checkout = _PACKAGE_DIR.parent
    if (checkout / "models" / "kuavo" / "params.yaml").is_file():
        return checkout
    shipped = _PACKAGE_DIR / "share"
    if (shipped / "models" / "kuavo" / "params.yaml").is_file():
        return shipped
    raise FileNotFoundError(
        "pr2_drake data folders not found: looked for models/kuavo/params.yaml in "
        f"{checkout} (source checkout) and {shipped} (installed wheel)"
    )


def data_path(*parts: str) -> Path:
    """A path below the data root, e.g. ``data_path("models", "kuavo", "kuavo.urdf")``."""
    if not parts or parts[0] not in _DATA_DIRS:
        raise ValueError(f"data_path must start with one of {_DATA_DIRS}, got {parts!r}")
    return data_root().joinpath(*parts)


def resolve_user_path(path: str | Path, kind: str) -> Path:
    """Resolve a user-given file: as given if it exists, else relative to the data root.

    Args:
        path: a path such as ``params/controllers/walking.yaml``.
        kind: what the file is, for the error message (e.g. "controller parameters").
    """
    p = Path(path)
    if p.is_file():
        return p
    candidate = data_root() / p
    if candidate.is_file():
        return candidate
    raise FileNotFoundError(f"{kind} file not found: {path} (also looked in {data_root()})")
