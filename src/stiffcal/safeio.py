"""Files a user names, checked before any work: input files that are regular files (a FIFO, a device, a socket
or a directory is refused at once, never read: reading a FIFO blocks until someone writes into it), read with a
bound on their size, and output directories that can be created and written before the first input is read.

Every problem is one :class:`~stiffcal.errors.InputError` naming the path (and the field it came from).
"""

from __future__ import annotations

import errno
import os
import stat
import tempfile
from pathlib import Path

from .errors import InputError

_KINDS = ((stat.S_ISFIFO, "a FIFO (named pipe)"), (stat.S_ISCHR, "a character device"),
          (stat.S_ISBLK, "a block device"), (stat.S_ISSOCK, "a socket"), (stat.S_ISDIR, "a directory"))


def file_kind(mode: int) -> str | None:
    """What a non-regular file is ('a FIFO (named pipe)', 'a directory', ...), None for a regular file."""
    if stat.S_ISREG(mode):
        return None
    return next((what for test, what in _KINDS if test(mode)), "not a regular file")


def _not_regular(what: str, path, source, field, expected: str) -> InputError:
    """'<source>: field '<field>': expected a regular file, but <path> is a FIFO ...' (source: the path itself
    when None)."""
    it = "it" if source is None or str(source) == str(path) else str(path)
    return InputError(f"expected {expected}, but {it} is {what}: refused without reading it",
                      source=str(path) if source is None else source, field=field)


def regular_file(path: str | os.PathLike, *, source: str | None = None, field: str | None = None,
                 expected: str = "a regular file") -> Path:
    """``path`` if it names an existing regular file (symbolic links followed); an InputError naming ``source``
    (default: the path itself) and ``field`` otherwise: no such file, a directory, a FIFO, a device, a socket."""
    p = Path(path)
    try:
        st = os.stat(p)
    except OSError as err:
        why = "no such file" if err.errno in (errno.ENOENT, errno.ENOTDIR) else f"cannot read it ({err.strerror})"
        raise InputError(f"{why}: {p}" if source is not None else why, source=source or str(p), field=field) from None
    what = file_kind(st.st_mode)
    if what:
        raise _not_regular(what, p, source, field, expected)
    return p


def read_bounded(path: str | os.PathLike, max_bytes: int, *, source: str | None = None, field: str | None = None,
                 what: str = "file") -> bytes:
    """The bytes of the regular file ``path``, at most ``max_bytes`` of them (a larger file is refused, naming the
    bound). The file is opened without blocking and checked on its open descriptor, so a FIFO put in its place
    after a check is refused too, never waited on."""
    p = regular_file(path, source=source, field=field)
    try:
        fd = os.open(p, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0))
    except OSError as err:
        raise InputError(f"cannot read {p} ({err.strerror})", source=source or str(p), field=field) from None
    with os.fdopen(fd, "rb") as fh:
        st = os.fstat(fh.fileno())
        kind = file_kind(st.st_mode)
        if kind:
            raise _not_regular(kind, p, source, field, "a regular file")
        if st.st_size > max_bytes:
            raise InputError(f"expected a {what} of at most {max_bytes:,} bytes, got {st.st_size:,}"
                             + (f" ({p})" if source else ""), source=source or str(p), field=field)
        data = fh.read(max_bytes + 1)
    if len(data) > max_bytes:  # it grew while we read it
        raise InputError(f"expected a {what} of at most {max_bytes:,} bytes, got more", source=source or str(p),
                         field=field)
    return data


def check_out_dir(out: str | os.PathLike, field: str | None = None) -> Path:
    """An output directory that can be written, checked before any work: ``out`` is a directory or does not
    exist yet; no folder on its way is a file; the nearest folder that exists is a directory in which a file can
    be created (tried: a temporary directory made and removed, so a read-only file system, /proc, or missing
    permissions are found, whoever runs it). InputError naming ``out`` otherwise (an empty path too: it would
    scatter the outputs into the current folder)."""
    if not str(out).strip():
        raise InputError("expected a directory to write into, got an empty path", field=field)
    out = Path(out)
    try:
        if out.exists() and not out.is_dir():
            what = file_kind(out.stat().st_mode) or "a file"
            raise InputError(f"expected a directory to write into, but it is {what}", source=str(out), field=field)
        probe = out
        while not probe.exists():
            if probe.is_symlink():
                raise InputError(f"expected a directory to write into, but {probe} is a broken symbolic link",
                                 source=str(out), field=field)
            parent = probe.parent
            if parent == probe:
                break
            probe = parent
    except OSError as err:  # e.g. a name too long, a loop of links
        raise InputError(f"expected a directory to write into, but it cannot be looked up ({err.strerror})",
                         source=str(out), field=field) from None
    if not probe.is_dir():
        raise InputError(f"expected a directory to write into, but {probe} on its way is a file, not a directory",
                         source=str(out), field=field)
    try:
        tempfile.TemporaryDirectory(prefix=".stiffcal-probe.", dir=probe).cleanup()
    except OSError as err:
        raise InputError(f"cannot write into {probe} ({err.strerror or err}); choose another output directory",
                         source=str(out), field=field) from None
    return out
