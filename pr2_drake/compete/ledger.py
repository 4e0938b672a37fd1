"""``OUT/episodes.jsonl``: one line per finished episode, each carrying a MAC.

The harness appends a row as each episode ends, from outside every sandbox, with an HMAC-SHA256
of the row under a key made for the results folder at its first run (``OUT/.episodes.key``,
readable by the harness's user only; the folder is hidden from agents). A resumed run trusts
only the rows whose MAC checks: a row anyone else wrote or changed is run again.
"""

from __future__ import annotations

import hashlib
import hmac
import json
import os
from pathlib import Path
from typing import Any, TextIO

KEY_FILE = ".episodes.key"
KEY_BYTES = 32


def run_key(out: Path) -> bytes:
    """The results folder's key (made on first use, mode 0600; a link is refused)."""
    path = out / KEY_FILE
    try:
        fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL | os.O_NOFOLLOW, 0o600)
    except FileExistsError:
        fd = os.open(path, os.O_RDONLY | os.O_NOFOLLOW)
        try:
            key = os.read(fd, KEY_BYTES + 1)
        finally:
            os.close(fd)
        if len(key) != KEY_BYTES:
            raise ValueError(f"{path}: not a key written by pr2-drake compete") from None
        return key
    try:
        key = os.urandom(KEY_BYTES)
        os.write(fd, key)
    finally:
        os.close(fd)
    return key


def _mac(row: dict[str, Any], key: bytes) -> str:
    body = json.dumps({k: v for k, v in row.items() if k != "mac"}, sort_keys=True,
                      separators=(",", ":"))
    return hmac.new(key, body.encode(), hashlib.sha256).hexdigest()


def append(f: TextIO, row: dict[str, Any], key: bytes) -> None:
    """Write ``row`` with its MAC as one line, and make it durable."""
    f.write(json.dumps({**row, "mac": _mac(row, key)}) + "\n")
    f.flush()
    os.fsync(f.fileno())


def read_rows(path: Path, key: bytes) -> tuple[dict[tuple[str, int, int], dict[str, Any]], int]:
    """The rows of ``path`` whose MAC checks, by (submission, task, seed), without their MAC;
    and how many lines were left out (cut off by a kill, or not written by the harness)."""
    done: dict[tuple[str, int, int], dict[str, Any]] = {}
    rejected = 0
    if not path.is_file():
        return done, rejected
    for line in path.read_text(errors="replace").splitlines():
        try:
            row = json.loads(line)
            mac = row.pop("mac")
            if not (isinstance(mac, str) and hmac.compare_digest(mac, _mac(row, key))):
                raise ValueError("bad MAC")
            done[(row["submission"], int(row["task"]), int(row["seed"]))] = row
        except (ValueError, KeyError, TypeError, AttributeError):
            rejected += bool(line.strip())
    return done, rejected
