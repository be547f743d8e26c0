"""Where a run's files come from: the git commit of the work tree and the reproducible date of its files (used by the
report, :mod:`stiffcal.report.html`, and the archive, :mod:`stiffcal.workflow.archive`)."""

from __future__ import annotations

import os
import subprocess
from pathlib import Path

from .errors import InputError


def git_output(args: list[str], root: Path) -> str | None:
    """The stripped output of ``git ARGS`` run in ``root``, or None when git is missing or fails."""
    try:
        return subprocess.run(["git", *args], cwd=root, capture_output=True, text=True, check=True).stdout.strip()
    except (OSError, subprocess.CalledProcessError):
        return None


def source_date_epoch(root: str | Path = ".") -> int:
    """``SOURCE_DATE_EPOCH`` if set, else the time of the current commit, else 0 (reproducible dates)."""
    env = os.environ.get("SOURCE_DATE_EPOCH")
    if env is not None:
        try:
            return int(env)
        except ValueError:
            raise InputError(f"expected an integer number of seconds, got {env!r}", field="SOURCE_DATE_EPOCH") from None
    t = git_output(["log", "-1", "--format=%ct"], Path(root))
    return int(t) if t else 0


def git_commit(root: str | Path = ".") -> str:
    """Current commit (short) with '-dirty' when the work tree has changes; 'unknown' outside git."""
    try:
        sha = subprocess.run(["git", "rev-parse", "--short=12", "HEAD"], cwd=root, capture_output=True,
                             text=True, check=True).stdout.strip()
        dirty = subprocess.run(["git", "status", "--porcelain", "--untracked-files=no"], cwd=root,
                               capture_output=True, text=True, check=True).stdout.strip()
        return sha + ("-dirty" if dirty else "")
    except (OSError, subprocess.CalledProcessError):
        return "unknown"
