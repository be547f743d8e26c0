"""The archive a reviewer gets: exactly the files one config's workflow made (its outputs, the logs of their jobs
with run times, the report), the effective config as the run saw it, every file that config refers to (robot
files and their URDFs, measured data, printed values), in one reproducible ``.tar.gz`` with ``provenance.json``
and ``SHA256SUMS``; and its verification.

The tarball is deterministic for given files: members sorted, owner 0, mode 0644, every time set to
``SOURCE_DATE_EPOCH`` (default: the commit's time), gzip header without a time. Only ``provenance.json``
carries the run's start and end times.
"""

from __future__ import annotations

import gzip
import hashlib
import io
import json
import os
import platform
import subprocess
import sys
import tarfile
from importlib import metadata
from pathlib import Path

from .errors import InputError

PACKAGES = ("stiffcal", "numpy", "scipy", "pandas", "matplotlib", "Jinja2", "PyYAML", "jsonschema", "snakemake",
            "weasyprint", "fonttools", "pydyf")
SUMS = "SHA256SUMS"
PROVENANCE = "provenance.json"


def _git(args: list[str], root: Path) -> str | None:
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
    t = _git(["log", "-1", "--format=%ct"], Path(root))
    return int(t) if t else 0


def provenance(config_hash: str, started: str, ended: str, root: str | Path = ".") -> dict:
    """What made the archive: commit and whether the tree was dirty, Python and package versions, platform,
    config hash, start and end times (ISO 8601, UTC)."""
    root = Path(root)
    commit = _git(["rev-parse", "HEAD"], root)
    dirty = None if commit is None else bool(_git(["status", "--porcelain", "--untracked-files=no"], root))
    versions = {}
    for name in PACKAGES:
        try:
            versions[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            versions[name] = None
    return {"commit": commit or "unknown", "dirty": dirty, "python": sys.version.split()[0],
            "packages": versions, "platform": platform.platform(), "machine": platform.machine(),
            "config_hash": config_hash, "started": started, "ended": ended,
            "source_date_epoch": source_date_epoch(root)}


def config_files(config, root: str | Path = ".") -> list[Path]:
    """Every input file the config refers to: each string value (at any depth) that names an existing file,
    relative to ``root`` (robot files, measured data CSVs, printed values), plus the URDF each robot file
    reads. Sorted, without repeats, as given (relative to ``root`` or absolute)."""
    from .robot import robot_inputs

    root = Path(root)
    found: set[Path] = set()

    def walk(v):
        if isinstance(v, dict):
            for x in v.values():
                walk(x)
        elif isinstance(v, list):
            for x in v:
                walk(x)
        elif isinstance(v, str) and v and (root / v).is_file():
            found.add(Path(v))
            urdfs = robot_inputs(root / v) if Path(v).suffix in (".yaml", ".yml") else []
            for u in urdfs:  # relative to root / v's folder: made relative to root again
                q = Path(u) if Path(v).is_absolute() else Path(os.path.relpath(u, root))
                if (root / q).is_file():
                    found.add(q)

    walk(config)
    return sorted(found, key=lambda p: p.as_posix())


def member_name(path: str | Path, root: str | Path = ".") -> str:
    """The name of a file in the archive: its path relative to root; a file outside root (an absolute path or
    one above root) goes under ``external/`` with its absolute path."""
    full = (Path(root) / path).resolve()
    try:
        return full.relative_to(Path(root).resolve()).as_posix()
    except ValueError:
        return "external/" + full.as_posix().lstrip("/")


def _sha256(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()


def write_archive(out: str | Path, files: list[Path], prov: dict, root: str | Path = ".") -> Path:
    """Write ``out`` (.tar.gz) with ``files`` (relative to root; names: :func:`member_name`), provenance.json
    and SHA256SUMS under one top directory named like the archive. Written to a temporary name and renamed:
    never a partial file. Raises :class:`InputError` naming a file that is missing, before anything is written."""
    out, root = Path(out), Path(root)
    top = out.name.removesuffix(".tar.gz")
    epoch = int(prov.get("source_date_epoch", 0))
    missing = [str(p) for p in files if not (root / p).is_file()]
    if missing:
        raise InputError(f"expected every file of the archive to exist; missing: {', '.join(missing)}",
                         source=str(out))
    members = {member_name(p, root): (root / p).read_bytes() for p in files}
    members[PROVENANCE] = (json.dumps(prov, indent=1, sort_keys=True, allow_nan=False) + "\n").encode()
    members[SUMS] = "".join(f"{_sha256(data)}  {name}\n" for name, data in sorted(members.items())).encode()
    buf = io.BytesIO()
    with tarfile.open(fileobj=buf, mode="w", format=tarfile.PAX_FORMAT) as tar:
        for name in sorted(members):
            info = tarfile.TarInfo(f"{top}/{name}")
            info.size, info.mtime, info.mode = len(members[name]), epoch, 0o644
            info.uid = info.gid = 0
            info.uname = info.gname = ""
            tar.addfile(info, io.BytesIO(members[name]))
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = out.with_name(out.name + ".part")
    with open(tmp, "wb") as fh, gzip.GzipFile(filename="", mode="wb", fileobj=fh, mtime=0) as gz:
        gz.write(buf.getvalue())
    tmp.replace(out)
    return out


def verify_archive(path: str | Path) -> tuple[int, list[str]]:
    """Check every member against SHA256SUMS. Returns (files verified, problems): one line per changed,
    missing or unlisted file, or one line saying that the compressed stream itself is damaged (gzip's own
    CRC-32 and length, checked over the whole stream first: a flipped byte or a damaged trailer). Raises
    :class:`InputError` when the file cannot be read or is not a stiffcal archive."""
    import zlib

    path = Path(path)
    try:
        raw = path.read_bytes()
    except OSError as err:
        raise InputError(f"cannot read file ({err.strerror})", source=str(path)) from None
    if raw[:2] != b"\x1f\x8b":
        raise InputError("not a readable .tar.gz archive (no gzip header)", source=str(path))
    try:
        tar_bytes = gzip.decompress(raw)
    except (OSError, EOFError, zlib.error) as err:
        return 0, [f"damaged: the compressed stream fails gzip's own check ({err}); no file in it can be trusted"]
    try:
        with tarfile.open(fileobj=io.BytesIO(tar_bytes), mode="r:") as tar:
            data = {m.name.split("/", 1)[1]: tar.extractfile(m).read() for m in tar.getmembers()
                    if m.isfile() and "/" in m.name}
    except (OSError, tarfile.TarError, EOFError) as err:
        return 0, [f"damaged: the tar stream inside cannot be read ({err}); no file in it can be trusted"]
    if SUMS not in data:
        raise InputError(f"no {SUMS} in the archive: not a stiffcal archive", source=str(path))
    listed = {}
    for line in data[SUMS].decode().splitlines():
        digest, _, name = line.partition("  ")
        listed[name] = digest
    problems = []
    for name, digest in sorted(listed.items()):
        if name not in data:
            problems.append(f"missing: {name}")
        elif _sha256(data[name]) != digest:
            problems.append(f"changed: {name}")
    problems += [f"not listed in {SUMS}: {name}" for name in sorted(set(data) - set(listed) - {SUMS})]
    return len(listed) - sum(p.startswith(("missing", "changed")) for p in problems), problems
