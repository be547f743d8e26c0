"""Exact fingerprints of inputs and a small on-disk memo, for work that a rerun would otherwise repeat.

:func:`feed` hashes the exact content of numbers, strings, arrays, dataclasses (a robot, a problem) and
containers; :func:`package_fingerprint` the source of the ``stiffcal`` package and the numerical libraries'
versions. :class:`JsonMemo` keeps a JSON mapping in one file, written whole (a temporary file renamed), read as
empty when it is missing or damaged. Users: the approximate-design cache of ``stiffcal design``
(:mod:`stiffcal.planning.designcache`) and the workflow's memo in ``.snakemake/stiffcal/`` (the code versions of the
rules, :func:`stiffcal.workflow.codeversion.remember_code_versions`, and the measured-data files its config check has
read, :func:`stiffcal.workflow.config.workflow_config`), so that ``snakemake -n`` with nothing to do does not parse the
package's source or reread every data file.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import os
from functools import lru_cache
from pathlib import Path

import numpy as np

#: where the workflow keeps its memos, relative to its working directory
WORKFLOW_MEMO_DIR = Path(".snakemake") / "stiffcal"


class NotFingerprintable(TypeError):
    """An input holds an object whose content :func:`feed` cannot read (the work is then not memoised)."""


def feed(h, obj) -> None:
    """Feed the exact content of obj to the hash h (type-tagged, so that 1, 1.0 and '1' differ). Dataclass fields
    whose names start with '_' are private caches, not inputs, and are skipped. Raises
    :class:`NotFingerprintable` for any other kind of object."""
    if obj is None:
        h.update(b"None;")
    elif isinstance(obj, (bool, int, float, str, np.generic)):
        h.update(f"{type(obj).__name__}:{obj!r};".encode())
    elif isinstance(obj, os.PathLike):
        feed(h, os.fspath(obj))
    elif isinstance(obj, np.ndarray):
        h.update(f"array:{obj.dtype.str}:{obj.shape};".encode())
        if obj.dtype == object:
            for item in obj.ravel():
                feed(h, item)
        else:
            h.update(np.ascontiguousarray(obj).tobytes())
    elif dataclasses.is_dataclass(obj) and not isinstance(obj, type):
        h.update(f"{type(obj).__module__}.{type(obj).__qualname__}{{".encode())
        for f in dataclasses.fields(obj):
            if f.name.startswith("_"):  # a private cache (a cell's collision engines), not an input
                continue
            h.update(f"{f.name}=".encode())
            feed(h, getattr(obj, f.name))
        h.update(b"}")
    elif isinstance(obj, (list, tuple)):
        h.update(f"{type(obj).__name__}[{len(obj)}]".encode())
        for item in obj:
            feed(h, item)
    elif isinstance(obj, dict):
        h.update(f"dict[{len(obj)}]".encode())
        for k in sorted(obj, key=repr):
            feed(h, k)
            feed(h, obj[k])
    else:
        raise NotFingerprintable(f"cannot fingerprint a {type(obj).__name__}")


def feed_file(h, path) -> None:
    """Feed a file's name and bytes (``<missing>`` for a file that is not there) to the hash h."""
    p = Path(path)
    feed(h, str(p))
    h.update(p.read_bytes() if p.is_file() else b"<missing>")


@lru_cache(maxsize=1)
def package_fingerprint() -> str:
    """SHA-256 of the ``stiffcal`` package's Python source and of the numerical libraries' versions (numpy,
    scipy, Pinocchio), read without importing them."""
    from importlib.metadata import PackageNotFoundError, version

    h = hashlib.sha256()
    root = Path(__file__).resolve().parent
    for path in sorted(root.rglob("*.py")):
        feed(h, path.relative_to(root).as_posix())
        h.update(path.read_bytes())
    versions = []
    for dist in ("numpy", "scipy", "pin"):
        try:
            versions.append(f"{dist} {version(dist)}")
        except PackageNotFoundError:
            versions.append(f"{dist} absent")
    feed(h, versions)
    return h.hexdigest()


def write_whole(path: Path, data: bytes) -> bool:
    """:func:`stiffcal.integrity.atomic_write` (a temporary file beside it, renamed; readable as the umask
    allows), False when the folder cannot be written: a memo that cannot be kept only costs the next run the
    work."""
    from .integrity import atomic_write

    try:
        atomic_write(path, data)
        return True
    except OSError:
        return False


class JsonMemo:
    """A JSON object kept in one file under one key (the package's fingerprint, say): :meth:`read` gives the
    mapping stored under ``key`` (empty when the file is missing, damaged or holds another key), :meth:`write`
    replaces the file whole with ``key`` and a mapping (so entries of an older key do not pile up)."""

    def __init__(self, path, key: str):
        self.path, self.key = Path(path), key
        self._doc: dict | None = None

    def read(self) -> dict:
        if self._doc is None:
            try:
                doc = json.loads(self.path.read_text(encoding="utf-8"))
                ok = isinstance(doc, dict) and doc.get("key") == self.key and isinstance(doc.get("entries"), dict)
                self._doc = doc["entries"] if ok else {}
            except (OSError, ValueError):
                self._doc = {}
        return self._doc

    def write(self, entries: dict) -> None:
        self._doc = dict(entries)
        write_whole(self.path, json.dumps({"key": self.key, "entries": self._doc}, sort_keys=True,
                                          allow_nan=False).encode())
