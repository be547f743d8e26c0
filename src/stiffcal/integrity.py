"""What the workflow writes is written whole, and what it reads is what was written.

* :func:`atomic_path` / :func:`atomic_write`: an output is written to a temporary file beside it and moved
  into place (``os.replace``, atomic on one file system) only when complete, so an interrupted or failed
  job never leaves a partial file that looks finished.
* :func:`record` / :func:`verify`: after a job, the SHA-256 of each of its outputs is recorded under
  ``.stiffcal/sha256/<output path>.sha256`` with the rule that made it; before a job, each of its inputs
  that has a record is checked against it. An intermediate file edited, truncated or damaged after it was
  made (a table changed by hand, a map cut in half) stops the job that would read it, with a message
  naming the file and the rule that made it, instead of flowing into the report. Deleting the file makes
  Snakemake rebuild it.
* :func:`watch_parent`: a job whose Snakemake process was killed stops too, instead of running on as an
  orphan.
"""

from __future__ import annotations

import contextlib
import hashlib
import os
from pathlib import Path

from .errors import InputError

#: where the checksums of the workflow's outputs are recorded (relative to the workflow root)
RECORDS = Path(".stiffcal") / "sha256"


@contextlib.contextmanager
def atomic_path(path: str | Path):
    """Yield a temporary path beside ``path``; move it onto ``path`` when the block ends without an error,
    delete it otherwise."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.name}.part{os.getpid()}{path.suffix}")
    try:
        yield tmp
        os.replace(tmp, path)
    finally:
        with contextlib.suppress(FileNotFoundError):
            tmp.unlink()


def atomic_write(path: str | Path, data: str | bytes) -> None:
    """Write text (UTF-8) or bytes to ``path`` atomically."""
    with atomic_path(path) as tmp:
        if isinstance(data, str):
            tmp.write_text(data, encoding="utf-8")
        else:
            tmp.write_bytes(data)


def sha256_file(path: str | Path) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def _record_path(path: str | Path, root: Path) -> Path:
    p = Path(path)
    rel = p.relative_to(root) if p.is_absolute() and p.is_relative_to(root) else p
    return root / RECORDS / f"{rel.as_posix()}.sha256"


def record(paths, rule: str, root: str | Path = ".") -> None:
    """Record the SHA-256 of every file of ``paths`` (a job's outputs), made by ``rule``."""
    root = Path(root).resolve()
    for p in paths:
        if Path(p).is_file():
            atomic_write(_record_path(p, root), f"{sha256_file(p)}  {rule}\n")


def recorded(path: str | Path, root: str | Path = ".") -> tuple[str, str] | None:
    """(digest, rule) recorded for ``path``, or None."""
    rec = _record_path(path, Path(root).resolve())
    if not rec.is_file():
        return None
    digest, _, rule = rec.read_text(encoding="utf-8").strip().partition("  ")
    return digest, rule


def verify(paths, root: str | Path = ".") -> None:
    """Check every file of ``paths`` (a job's inputs) that has a record against it; raise
    :class:`InputError` naming the first file that changed, and the rule that made it."""
    for p in paths:
        rec = recorded(p, root)
        if rec is not None and Path(p).is_file() and sha256_file(p) != rec[0]:
            raise InputError(f"changed after rule {rec[1]} wrote it (its SHA-256 is not the one recorded in "
                             f"{RECORDS}/): it was edited, cut short or damaged. Delete it and rerun: the workflow "
                             "rebuilds it", source=str(p))


def watch_parent(marker: str = "snakemake", interval_s: float = 2.0) -> None:
    """Exit this process (status 3) as soon as its nearest ancestor whose command line contains ``marker``
    is gone: a job of a killed Snakemake run stops instead of running on as an orphan. Outputs are written
    atomically, so nothing partial is left. Does nothing outside Snakemake."""
    import threading

    try:
        import psutil

        ancestor = next((p for p in psutil.Process().parents() if marker in " ".join(p.cmdline())), None)
    except Exception:  # noqa: BLE001 - no psutil, or a process we may not inspect: no watchdog
        return
    if ancestor is None:
        return

    def watch():
        import time

        while True:
            time.sleep(interval_s)
            if not ancestor.is_running():
                os._exit(3)

    threading.Thread(target=watch, name="stiffcal-watch-parent", daemon=True).start()
