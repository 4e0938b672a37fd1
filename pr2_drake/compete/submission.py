"""Submissions are data: the harness reads only their ``submission.yaml`` (a regular file, not
followed through a link) and lets the agent see the rest read-only in its sandbox, after
:func:`check_submission` found no symbolic link leading out of the folder."""

from __future__ import annotations

import os
import stat
from pathlib import Path

MAX_YAML_BYTES = 1 << 16  # a longer submission.yaml is not one [bytes]


def read_submission_yaml(file: Path) -> str:
    """The text of a submission's ``submission.yaml``, opened without following a link.

    Raises:
        ValueError: it is a link, not a regular file, too long or not UTF-8.
    """
    try:
        fd = os.open(file, os.O_RDONLY | os.O_NOFOLLOW | os.O_NONBLOCK | os.O_CLOEXEC)
    except OSError as e:
        raise ValueError(f"{file}: cannot be opened without following a link "
                         f"({os.strerror(e.errno)})") from None
    try:
        if not stat.S_ISREG(os.fstat(fd).st_mode):
            raise ValueError(f"{file}: not a regular file")
        data = os.read(fd, MAX_YAML_BYTES + 1)
    finally:
        os.close(fd)
    if len(data) > MAX_YAML_BYTES:
        raise ValueError(f"{file}: longer than {MAX_YAML_BYTES} bytes")
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError:
        raise ValueError(f"{file}: not UTF-8 text") from None


def check_submission(folder: Path, foreign_uid: bool) -> str:
    """Why ``folder`` cannot be given to an agent ("" when it can): a symbolic link that
    leads out of it (or nowhere inside it), or, when the agent runs as a uid of its own
    (``foreign_uid``), a file or folder that other users cannot read. Links are never
    followed: their targets are resolved as text against the folder."""
    root = Path(os.path.abspath(folder))
    if root.is_symlink() or not root.is_dir():
        return f"{root} is not a folder (a link to one is refused)"
    for dirpath, dirnames, filenames in os.walk(root, followlinks=False):
        for name in dirnames + filenames:
            path = Path(dirpath) / name
            try:
                st = os.lstat(path)
            except OSError:
                continue
            if stat.S_ISLNK(st.st_mode):
                target = _resolve_inside(root, path)
                if target is None:
                    return (f"{path.relative_to(root)} is a symbolic link to "
                            f"{os.readlink(path)!r}, outside the submission")
            elif foreign_uid and st.st_mode & _readable(st.st_mode) != _readable(st.st_mode):
                return (f"{path.relative_to(root)} is not readable by other users "
                        f"(chmod -R o+rX {root})")
    return ""


def _readable(mode: int) -> int:
    return stat.S_IROTH | (stat.S_IXOTH if stat.S_ISDIR(mode) else 0)


def _resolve_inside(root: Path, link: Path, depth: int = 0) -> Path | None:
    """Where ``link`` leads, resolved as text inside ``root`` (None: out of it, a loop)."""
    if depth > 40:
        return None
    target = os.readlink(link)
    here = Path(os.path.normpath(Path(link.parent) / target))  # an absolute target stays
    if here != root and root not in here.parents:
        return None
    # A link on the way (or the target itself) must lead inside too.
    walked = root
    for part in here.relative_to(root).parts:
        walked = walked / part
        if walked.is_symlink():
            inner = _resolve_inside(root, walked, depth + 1)
            if inner is None:
                return None
            walked = inner
    return walked
