"""Remove Snakemake's lock on this directory when no Snakemake process is running in it (`make report` and
`make archive` call this first).

A Snakemake run that was killed (Ctrl-C twice, a closed terminal, `kill -9`) leaves a lock in
`.snakemake/locks/`, and the next run stops with "Directory cannot be locked". Unlocking is safe only when no
other Snakemake process works in this directory, so this looks for one (any process whose command line
names snakemake and whose working directory is this one) and unlocks only when there is none. Jobs that
the killed run left half done are rerun by the profile's `rerun-incomplete: true`.
"""

import os
import subprocess
import sys
from pathlib import Path

import psutil


def running_here(root: Path) -> list[int]:
    """PIDs of other processes running snakemake with this working directory."""
    me = os.getpid()
    found = []
    for p in psutil.process_iter(["pid", "cmdline", "cwd"]):
        try:
            cmd = " ".join(p.info["cmdline"] or [])
            if p.info["pid"] != me and "snakemake" in cmd and "unlock_if_idle" not in cmd \
                    and p.info["cwd"] and Path(p.info["cwd"]).resolve() == root:
                found.append(p.info["pid"])
        except (psutil.Error, OSError):
            continue
    return found


def main() -> int:
    root = Path.cwd().resolve()
    locks = root / ".snakemake" / "locks"
    if not locks.is_dir() or not any(locks.iterdir()):
        return 0
    others = running_here(root)
    if others:
        print(f"unlock_if_idle: Snakemake is running here (pid {', '.join(map(str, others))}); the lock stays",
              file=sys.stderr)
        return 0
    snakemake = Path(sys.executable).with_name("snakemake")
    subprocess.run([str(snakemake), "--unlock", "--cores", "1", *sys.argv[1:]], check=True, capture_output=True)
    print("unlock_if_idle: removed the lock of an interrupted Snakemake run (no Snakemake process runs here)",
          file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
