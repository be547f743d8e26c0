"""The docs' lists that are derived from the registries (issue 26): the design criteria
(:data:`stiffcal.model.criteria.CRITERIA`) in docs/contracts.md and the catalogue's causes
(:data:`stiffcal.model.catalogue.CATALOGUE`) in docs/measured-data.md. Each sits between the markers
``<!-- registry:NAME -->`` and ``<!-- /registry:NAME -->``; ``make docs`` rewrites them from the registries, and
tests/test_docs.py fails, naming the block, when a block is not what the registry gives.

Run: .venv/bin/python tools/registry_docs.py [--check]
"""

from __future__ import annotations

import argparse
import re
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "src"))

#: the files that hold registry blocks, relative to the repository
FILES = ("docs/contracts.md", "docs/measured-data.md")


def criteria_block() -> str:
    """The table of the design criteria: key (the CLI's ``--criterion``, the config's ``study.criteria``), name,
    sense and formula."""
    from stiffcal.model.criteria import CRITERIA

    rows = ["A: the observation matrices A_i of the m poses stacked (eqs. 5-6), A^T A the information matrix; "
            "sigma_1 >= ... >= sigma_s: the singular values of A; A_t: the test pose's; d[X]: the diagonal of X.", "",
            "| key | criterion | optimum | formula |", "|---|---|---|---|"]
    rows += [f"| `{c.key}` | {c.label} | {c.sense} | `{c.formula}` |" for c in CRITERIA.values()]
    return "\n".join(rows)


def causes_block() -> str:
    """The list of the catalogue's causes, in the order of every model's parameters: name, kind, law."""
    from stiffcal.model.catalogue import CATALOGUE

    kinds = {"joint": "at the joints", "link": "in the links", "measurement": "the measuring system's"}
    lines = []
    for c in CATALOGUE.values():
        total = ", on the total torque: the arm's own weight's and the load's" if c.preloaded else ""
        lines.append(f"  - `{c.name}` ({kinds[c.kind]}{total}): {c.meaning}")
    return "\n".join(lines)


BLOCKS = {"criteria": criteria_block, "causes": causes_block}


def _pattern(name: str) -> re.Pattern:
    return re.compile(rf"(<!-- registry:{name} -->\n)(.*?)( *<!-- /registry:{name} -->)", re.S)


def rewritten(text: str) -> str:
    """``text`` with every registry block it holds replaced by the registry's."""
    for name, block in BLOCKS.items():
        text = _pattern(name).sub(lambda m, b=block: m.group(1) + b() + "\n" + m.group(3), text)
    return text


def blocks_in(text: str) -> dict[str, str]:
    """The registry blocks ``text`` holds: name -> its content."""
    return {name: m.group(2).removesuffix("\n") for name in BLOCKS for m in [_pattern(name).search(text)] if m}


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--check", action="store_true", help="only report stale blocks (exit status 1)")
    args = parser.parse_args()
    stale = []
    for rel in FILES:
        path = ROOT / rel
        text = path.read_text(encoding="utf-8")
        new = rewritten(text)
        if new != text:
            stale.append(rel)
            if not args.check:
                path.write_text(new, encoding="utf-8")
    for rel in stale:
        print(f"{rel}: {'stale' if args.check else 'rewritten'}")
    return 1 if args.check and stale else 0


if __name__ == "__main__":
    sys.exit(main())
