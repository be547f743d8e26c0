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
import sys
import tarfile
from importlib import metadata
from pathlib import Path

from ..errors import InputError, short_repr
from ..provenance import git_commit, git_output, source_date_epoch

#: every library that reads, computes or writes the data (their versions go into provenance.json): the numerics,
#: Pinocchio (``pin``, with the C++ library and urdfdom, its URDF parser: every URDF robot file is read by them),
#: python-flint (exact root isolation in the maps), the readers of robot
#: files, configs and URDFs, the figures, the report and the PDF
PACKAGES = ("stiffcal", "numpy", "scipy", "pandas", "matplotlib", "pillow", "pin", "libpinocchio",
            "eigenpy", "coal", "libcoal", "cmeel-assimp", "cmeel-urdfdom", "cmeel-tinyxml2", "python-flint", "Jinja2",
            "PyYAML", "jsonschema", "defusedxml", "snakemake", "weasyprint", "fonttools", "pydyf", "tqdm")
SUMS = "SHA256SUMS"
PROVENANCE = "provenance.json"


def input_status(inputs, root: str | Path = ".") -> dict[str, list[str]]:
    """Which of ``inputs`` (the config file, robot files, URDFs, data: paths relative to ``root`` or absolute) git
    does not vouch for: ``untracked`` (not in the current commit: new, ignored, staged only, or outside the
    repository) and ``modified`` (in the commit, but changed since), each sorted, as given. Outside a git work
    tree every input is untracked."""
    root = Path(root)
    names = sorted({Path(p).as_posix() for p in inputs})
    top = git_output(["rev-parse", "--show-toplevel"], root) if names else None
    if top is None:
        return {"untracked": names, "modified": []}
    rel = {}
    for n in names:
        full = (root / n).resolve()
        if full.is_relative_to(Path(top).resolve()):
            rel[n] = Path(os.path.relpath(full, root.resolve())).as_posix()
    paths = sorted(set(rel.values()))

    def listed(args):
        out = git_output([*args, "--", *paths], root) if paths else ""
        return {Path(x).as_posix() for x in (out or "").split("\0") if x}

    committed = listed(["ls-tree", "-r", "-z", "--name-only", "HEAD"])
    changed = listed(["diff", "--name-only", "-z", "--relative", "HEAD"])
    return {"untracked": sorted(n for n in names if rel.get(n) not in committed),
            "modified": sorted(n for n in names if rel.get(n) in committed and rel[n] in changed)}


def code_outside_tree(root: str | Path = ".") -> str | None:
    """The folder of the stiffcal package this process imported when it is not inside the work tree ``root``
    (another clone's, or an installed copy: the run's code is then not the commit's, which ``-dirty`` and this
    path say), else None."""
    package = Path(__file__).resolve().parents[1]
    try:
        package.relative_to(Path(root).resolve())
    except ValueError:
        return str(package)
    return None


def provenance(config_hash: str, started: str, ended: str, root: str | Path = ".", inputs=()) -> dict:
    """What made the archive: commit and whether the tree was dirty, the run's inputs that git does not vouch
    for (:func:`input_status`: ``untracked_inputs``, ``modified_inputs``; any of them makes ``dirty`` true),
    Python and the versions of every library that touched the data (:data:`PACKAGES`), platform, config hash,
    start and end times (ISO 8601, UTC). inputs: the files the run read (the config file, and
    :func:`config_files`)."""
    root = Path(root)
    commit = git_output(["rev-parse", "HEAD"], root)
    status = input_status(inputs, root)
    outside = code_outside_tree(root)
    dirty = None if commit is None else bool(git_output(["status", "--porcelain", "--untracked-files=no"], root)
                                             or status["untracked"] or status["modified"] or outside)
    return {"commit": commit or "unknown", "dirty": dirty, "untracked_inputs": status["untracked"],
            "modified_inputs": status["modified"], "code_outside_tree": outside, "python": sys.version.split()[0],
            "packages": package_versions(), "platform": platform.platform(), "machine": platform.machine(),
            "config_hash": config_hash, "started": started, "ended": ended,
            "source_date_epoch": source_date_epoch(root)}


def run_status(config, root: str | Path = ".", config_source: str | None = None, packages: bool = True) -> dict:
    """What the report and the archive's name say of a run: ``commit`` (12 hex digits, '-dirty' when the work tree
    has changes or an input git does not vouch for, or the code that ran is not the tree's: ``code_outside_tree``,
    :func:`code_outside_tree`), ``untracked_inputs`` and ``modified_inputs``
    (:func:`input_status` of ``config_source``, the config file, and :func:`config_files`) with their SHA-256
    (``input_sha256``, :func:`input_digests`), and ``packages``
    (the installed version of every library of :data:`PACKAGES`, those installed; left out with
    ``packages=False``)."""

    status = input_status([*config_files(config, root), *([config_source] if config_source else [])], root)
    commit = git_commit(root)
    outside = code_outside_tree(root)
    if commit != "unknown" and not commit.endswith("-dirty") and (status["untracked"] or status["modified"]
                                                                   or outside):
        commit += "-dirty"
    out = {"commit": commit, "untracked_inputs": status["untracked"], "modified_inputs": status["modified"],
           "code_outside_tree": outside,
           "input_sha256": input_digests([*status["untracked"], *status["modified"]], root)}
    if packages:
        out["packages"] = {k: v for k, v in package_versions().items() if v is not None}
    return out


def input_digests(paths, root: str | Path = ".") -> dict[str, str]:
    """{path: SHA-256 hex digest} of the files ``paths`` (relative to ``root``; those that exist): what pins an
    input git does not vouch for (a fresh reviewer could not tell from the report which of two versions of an
    untracked data file was analysed)."""
    import hashlib

    out = {}
    for p in paths:
        f = Path(root) / p
        if f.is_file():
            out[str(p)] = hashlib.sha256(f.read_bytes()).hexdigest()
    return out


def package_versions() -> dict[str, str | None]:
    """{distribution: installed version or None} for every library of :data:`PACKAGES`."""
    versions = {}
    for name in PACKAGES:
        try:
            versions[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            versions[name] = None
    return versions


def config_files(config, root: str | Path = ".") -> list[Path]:
    """Every input file the config refers to: each string value (at any depth) that names an existing file,
    relative to ``root`` (robot files, measured data CSVs, printed values), plus the URDF each robot file
    reads. Sorted, without repeats, as given (relative to ``root`` or absolute)."""
    from ..model.robot import robot_inputs

    root = Path(root)
    found: set[Path] = set()

    def walk(v, cell=False):
        if isinstance(v, dict):  # a study's robot with the study's cell reads the URDF's meshes
            for k, x in v.items():
                walk(x, k == "robot" and v.get("cell") is not None)
        elif isinstance(v, list):
            for x in v:
                walk(x)
        elif isinstance(v, str) and v and (root / v).is_file():
            found.add(Path(v))
            urdfs = robot_inputs(root / v, cell) if Path(v).suffix in (".yaml", ".yml") else []
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


#: the most a checked archive may hold once decompressed [bytes], and the most members it may have: a results
#: archive is tens of megabytes; beyond these it is refused as not a stiffcal archive (a gzip bomb)
MAX_UNPACKED_BYTES = 2 * 1024**3
MAX_MEMBERS = 100_000
#: the largest SHA256SUMS read [bytes]
MAX_SUMS_BYTES = 16 * 1024**2
_CHUNK = 1 << 20


def _gzip_problem(path: Path) -> str | None:
    """Decompress the whole gzip stream once, discarding its bytes, to check its own CRC-32 and length (every
    member); refuse (InputError) a stream that expands beyond :data:`MAX_UNPACKED_BYTES`. Returns the problem
    ('damaged: ...') or None."""
    import zlib

    total = 0
    try:
        with gzip.open(path, "rb") as gz:
            while block := gz.read(_CHUNK):
                total += len(block)
                if total > MAX_UNPACKED_BYTES:
                    raise InputError(f"expands to more than {MAX_UNPACKED_BYTES // 1024**3} GiB when decompressed: not "
                                     "a stiffcal archive (refused before reading further: the largest checked; "
                                     "docs/contracts.md, 'Limits')", source=str(path))
    except (OSError, EOFError, zlib.error) as err:
        return f"damaged: the compressed stream fails gzip's own check ({err}); no file in it can be trusted"
    return None


def _read_sums(data: bytes) -> tuple[dict[str, str], str | None]:
    """({name: sha256 hex digest}, problem) from the bytes of SHA256SUMS; a line that is not UTF-8 or not
    ``<64 hex digits>  <name>`` makes the problem ('damaged: ...'), naming the line."""
    import re

    listed = {}
    for k, line in enumerate(data.split(b"\n"), start=1):
        if not line:
            continue
        try:
            text = line.decode("utf-8")
        except UnicodeDecodeError as err:
            return listed, (f"damaged: {SUMS} line {k} is not UTF-8 text (byte 0x{line[err.start]:02x}); no file in "
                            "the archive can be trusted")
        digest, sep, name = text.partition("  ")
        if not sep or not name or not re.fullmatch(r"[0-9a-f]{64}", digest):
            return listed, (f"damaged: {SUMS} line {k} is not '<SHA-256>  <file>' ({short_repr(text, 60)}); no file in "
                            "the archive can be trusted")
        if name in listed:
            return listed, (f"damaged: {SUMS} line {k} lists {printable(name)} a second time; no file in the archive "
                            "can be trusted")
        listed[name] = digest
    return listed, None


#: the largest extended header (a GNU long name, a PAX header) read [bytes]: Python's tarfile reads one whole
MAX_HEADER_BYTES = 1024**2


class _BoundedInfo(tarfile.TarInfo):
    """A tar header whose extended headers (long names, PAX records) are refused beyond :data:`MAX_HEADER_BYTES`
    before tarfile reads them into memory."""

    def _proc_member(self, tarfile_):
        extended = (tarfile.GNUTYPE_LONGNAME, tarfile.GNUTYPE_LONGLINK, tarfile.XHDTYPE, tarfile.XGLTYPE,
                    tarfile.SOLARIS_XHDTYPE)
        if self.type in extended and self.size > MAX_HEADER_BYTES:
            raise InputError(f"holds an extended tar header (a long name or PAX record) of {self.size:,} bytes (at "
                             f"most {MAX_HEADER_BYTES:,}): not a stiffcal archive (docs/contracts.md, 'Limits')")
        return super()._proc_member(tarfile_)


def printable(name: str) -> str:
    """A member name as one line of text: control characters (a newline, an escape) written as escapes, so that a
    name cannot forge lines of the report."""
    return name if name.isprintable() else name.encode("unicode_escape").decode("ascii")


def _unsafe(name: str) -> bool:
    """A member name that extraction would write outside the archive's folder, or that names no file: absolute,
    with a '..', '.' or empty component, or a backslash (a Windows separator)."""
    parts = name.split("/")
    return name.startswith("/") or "\\" in name or any(p in ("", ".", "..") for p in parts)


def _hash_members(tar, path: Path) -> dict:
    """Read the members of the open stream ``tar`` once: {"digests": {(top, name): SHA-256}, "sums": {top: the bytes
    of its SHA256SUMS}, "odd": {(top, name)} not regular files, "loose": member names outside any top directory,
    "unsafe": unsafe member names, "twice": member names met more than once}. Bounds the members' count and their
    total size as recorded in the headers (a sparse member expands beyond its bytes)."""
    out = {"digests": {}, "sums": {}, "odd": set(), "loose": [], "unsafe": [], "twice": []}
    seen, total = set(), 0
    for count, m in enumerate(tar, start=1):
        if count > MAX_MEMBERS:
            raise InputError(f"more than {MAX_MEMBERS:,} members: not a stiffcal archive (docs/contracts.md, "
                             "'Limits')", source=str(path))
        total += max(m.size, 0)
        if total > MAX_UNPACKED_BYTES:
            raise InputError(f"its members add up to more than {MAX_UNPACKED_BYTES // 1024**3} GiB (as their headers "
                             "record, sparse members included): not a stiffcal archive (docs/contracts.md, 'Limits')",
                             source=str(path))
        full = m.name.rstrip("/") if m.isdir() else m.name
        if _unsafe(full):
            out["unsafe"].append(m.name)
            continue
        if full in seen and not m.isdir():
            out["twice"].append(full)
        seen.add(full)
        top, sep, name = full.partition("/")
        if not sep:
            if not m.isdir():
                out["loose"].append(full)
            continue
        if not m.isfile():
            if not m.isdir():
                out["odd"].add((top, name))
            continue
        fh = tar.extractfile(m)
        if name == SUMS:
            if m.size > MAX_SUMS_BYTES:
                raise InputError(f"its {SUMS} has {m.size:,} bytes (at most {MAX_SUMS_BYTES:,}): not a "
                                 "stiffcal archive", source=str(path))
            out["sums"][top] = fh.read()
            continue
        h = hashlib.sha256()
        while block := fh.read(_CHUNK):
            h.update(block)
        out["digests"][(top, name)] = h.hexdigest()
    return out


def verify_archive(path: str | Path) -> tuple[int, list[str]]:
    """Check every member against SHA256SUMS. Returns (files verified, problems): one line per changed,
    missing or unlisted file, a member that is not a regular file, one outside the archive's one top directory (the
    one that holds SHA256SUMS) or with an unsafe name (absolute, '..'), a member met twice (extraction keeps one
    copy, maybe not the one checked), a SHA256SUMS that lists a name twice, nothing, or not provenance.json, or one
    line saying that the compressed stream itself is damaged (gzip's own CRC-32 and length, checked over the whole
    stream first: a flipped byte or a damaged trailer) or that SHA256SUMS is unreadable. Names are printed with
    control characters escaped. Raises :class:`InputError` when the file cannot be read (a FIFO, a device or a
    directory is refused at once), is not a gzip stream, expands beyond :data:`MAX_UNPACKED_BYTES` (counted while
    decompressing, and as the members' headers record: a sparse member), holds more than :data:`MAX_MEMBERS`
    members or an extended header beyond :data:`MAX_HEADER_BYTES` (a gzip or tar bomb), or has no top directory
    with a SHA256SUMS (not a stiffcal archive). Members are read one at a time and hashed in blocks: memory stays
    small whatever the archive holds."""
    from ..safeio import regular_file

    path = regular_file(path, expected="a results archive (.tar.gz)")
    if read_bounded_head(path) != b"\x1f\x8b":
        raise InputError("not a readable .tar.gz archive (no gzip header)", source=str(path))
    damaged = _gzip_problem(path)
    if damaged:
        return 0, [damaged]
    try:
        with tarfile.open(path, mode="r|gz", tarinfo=_BoundedInfo) as tar:
            found = _hash_members(tar, path)
    except InputError as err:
        raise InputError(err.message, source=str(path)) from None
    except (OSError, tarfile.TarError, EOFError) as err:
        return 0, [f"damaged: the tar stream inside cannot be read ({err}); no file in it can be trusted"]
    if not found["sums"]:
        raise InputError(f"no top directory holds a {SUMS}: not a stiffcal archive", source=str(path))
    tops = sorted(found["sums"])
    top = tops[0]
    problems = [f"several top directories hold a {SUMS} ({', '.join(map(printable, tops))}): which one is the "
                "archive cannot be told"] if len(tops) > 1 else []
    listed, bad_sums = _read_sums(found["sums"][top])
    if bad_sums:
        return 0, problems + [bad_sums]
    digests = {name: d for (t, name), d in found["digests"].items() if t == top}
    odd = {name for t, name in found["odd"] if t == top}
    outside = sorted({*found["loose"], *(f"{t}/{name}" for t, name in [*found["digests"], *found["odd"]] if t != top)})
    problems += [f"unsafe member name (absolute, or with '..', '.' or an empty part): {printable(n)}"
                 for n in found["unsafe"]]
    problems += [f"outside the archive's top directory ({printable(top)}): {printable(n)}" for n in outside]
    problems += [f"in the archive twice (extraction keeps one copy, maybe not the one checked): {printable(n)}"
                 for n in sorted(set(found["twice"]))]
    if PROVENANCE not in listed:
        problems.append(f"{SUMS} does not list {PROVENANCE}" + (" (it lists no file)" if not listed else "") +
                        ": not a complete stiffcal archive")
    problems += [f"unsafe name listed in {SUMS} (absolute, or with '..', '.' or an empty part): {printable(name)}"
                 for name in sorted(listed) if _unsafe(name)]
    for name, digest in sorted(listed.items()):
        if name not in digests:
            problems.append(f"missing: {printable(name)}" + (" (not a regular file in the archive)" if name in odd
                                                             else ""))
        elif digests[name] != digest:
            problems.append(f"changed: {printable(name)}")
    problems += [f"not listed in {SUMS}: {printable(name)}" for name in sorted(set(digests) - set(listed))]
    problems += [f"not a regular file (a link or a device) in the archive: {printable(name)}"
                 for name in sorted(odd - set(listed))]
    return sum(1 for name in listed if digests.get(name) == listed[name]), problems


def read_bounded_head(path: Path, size: int = 2) -> bytes:
    """The first ``size`` bytes of a regular file (opened without blocking); InputError if it cannot be read."""
    try:
        fd = os.open(path, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0))
        with os.fdopen(fd, "rb") as fh:
            return fh.read(size)
    except OSError as err:
        raise InputError(f"cannot read file ({err.strerror})", source=str(path)) from None
