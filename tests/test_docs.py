"""The user-facing docs are complete and in the repository: the config keys of docs/contracts.md are exactly
the schema's, every contract lives in docs/ (no reference to a design file outside the repository), and the
licence and citation files agree with pyproject.toml."""

import re
import subprocess

import pytest
import yaml

from stiffcal.validation import load_schema


def schema_keys(schema: dict, prefix: str = "") -> set[str]:
    """Every key of a JSON schema as a dotted path, list items as '[]': 'maps.studies[].name'."""
    keys = set()
    for name, sub in schema.get("properties", {}).items():
        path = f"{prefix}{name}"
        keys.add(path)
        keys |= schema_keys(sub, path + ".")
        if sub.get("type") == "array" and isinstance(sub.get("items"), dict):
            keys |= schema_keys(sub["items"], path + "[].")
    return keys


def documented_config_keys(text: str) -> set[str]:
    section = text[text.index("## Workflow config"):]
    section = section[:section.index("\n## ", 10)]
    return set(re.findall(r"^\| `([^`]+)` \|", section, flags=re.M))


def test_config_keys_in_the_docs_are_the_schemas(root):
    documented = documented_config_keys((root / "docs/contracts.md").read_text(encoding="utf-8"))
    keys = schema_keys(load_schema("config"))
    assert documented - keys == set(), "documented but not in the schema"
    assert keys - documented == set(), "in the schema but not documented"


def test_contracts_are_in_the_repository(root):
    """No file points users at a design document outside the repository."""
    files = subprocess.run(["git", "ls-files"], cwd=root, capture_output=True, text=True, check=True).stdout.split()
    offenders = [f for f in files if not f.startswith("tests/")
                 and (root / f).is_file() and f.endswith((".py", ".md", ".yaml", ".smk", ".j2", ".cff", ".toml"))
                 and "DESIGN.md" in (root / f).read_text(encoding="utf-8", errors="replace")]
    assert offenders == []
    for part in ("## Robot files", "## Workflow config", "## Command line", "## Measured-data CSV", "## Verdict JSON"):
        assert part in (root / "docs/contracts.md").read_text(encoding="utf-8")


def test_licence_and_citation(root):
    assert (root / "LICENSE").read_text().startswith("MIT License")
    assert 'license = {text = "MIT"}' in (root / "pyproject.toml").read_text()
    cff = yaml.safe_load((root / "CITATION.cff").read_text(encoding="utf-8"))
    paper = cff["preferred-citation"]
    assert cff["license"] == "MIT" and paper["year"] == 2012
    assert paper["title"] == ("Optimality criteria for measurement poses selection in calibration of robot stiffness "
                              "parameters")
    assert [a["family-names"] for a in paper["authors"]] == ["Wu", "Klimchik", "Pashkevich", "Caro", "Furet"]


def test_every_limit_is_documented_with_its_value(root):
    """docs/contracts.md, "Limits": a row for every bound of stiffcal.limits (and the archive's and robot's), with
    the value the code uses."""
    from stiffcal import limits
    from stiffcal.workflow import archive
    from stiffcal.model import robot

    text = (root / "docs/contracts.md").read_text(encoding="utf-8")
    section = text[text.index("## Limits"):]
    rows = {}
    for line in section.splitlines():
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        if len(cells) >= 2 and cells[0].startswith("`"):
            for name in re.findall(r"`([A-Z_]+)`", cells[0]):
                rows[name] = cells[1]
    constants = {k: getattr(limits, k) for k in dir(limits)
                 if k.isupper() and isinstance(getattr(limits, k), (int, float))}
    constants |= {"MIN_COMPLIANCE": robot.MIN_COMPLIANCE, "MAX_UNPACKED_BYTES": archive.MAX_UNPACKED_BYTES,
                  "MAX_MEMBERS": archive.MAX_MEMBERS}
    scale = {"MAX_URDF_BYTES": 1e6, "MAX_UNPACKED_BYTES": 2**30}
    missing = sorted(set(constants) - set(rows) - {"MIN_MEMORY_MB"})
    assert missing == [], "limits not in the docs' table"
    assert "`MIN_MEMORY_MB` = 1024" in section and limits.MIN_MEMORY_MB == 1024
    for name, value in constants.items():
        if name not in rows:
            continue
        found = re.findall(r"\d[\d,]*(?:\.\d+)?(?:e-?\d+)?", rows[name])
        numbers = [float(x.replace(",", "")) * scale.get(name, 1) for x in found]
        assert any(abs(x - value) <= 1e-9 * abs(value) for x in numbers), (name, value, rows[name])


def test_cell_keys_in_the_docs_are_the_schemas(root):
    """docs/contracts.md, "The cell": one row per key of cell.schema.yaml, no more."""
    text = (root / "docs/contracts.md").read_text(encoding="utf-8")
    section = text[text.index("## The cell"):]
    section = section[:section.index("\n## ", 10)]
    documented = set(re.findall(r"^\| `([^`]+)` \|", section, flags=re.M))
    assert documented == set(load_schema("cell")["properties"])


@pytest.mark.parametrize("kind, heading, first_column", [
    ("Verdict", "## The verdict", "field"), ("DiscriminationPlan", "## The next experiment", "field of `plan.json`")])
def test_result_fields_in_the_docs_are_the_type_s(root, kind, heading, first_column):
    """The tables of verdict.json and plan.json in docs/measured-data.md name exactly the fields of
    stiffcal.measured.results.Verdict and DiscriminationPlan (the types the API returns and the files are written from;
    issue 26: nothing checked them before, and plan.json's robot and data were not documented)."""
    from stiffcal.measured import results

    text = (root / "docs/measured-data.md").read_text(encoding="utf-8")
    section = text.split(heading, 1)[1].split("\n## ", 1)[0]
    table = section.split(f"| {first_column} | meaning |", 1)[1].split("\n\n", 1)[0]
    named = [name for line in table.splitlines() if line.startswith("| `")
             for name in re.findall(r"`([a-z_0-9]+)`", line.split(" | ", 1)[0])]
    assert sorted(named) == sorted(results.documented_fields(getattr(results, kind)))
    assert len(named) == len(set(named))


def test_the_docs_lists_written_from_the_registries_are_current(root):
    """Every list of docs/ that is written from a registry (the criteria, the catalogue's causes; between
    ``<!-- registry:NAME -->`` markers) is what ``make docs`` (tools/registry_docs.py) writes from the registry
    now: a registry entry added without ``make docs`` fails here, naming the file and the block."""
    import importlib.util

    spec = importlib.util.spec_from_file_location("registry_docs", root / "tools/registry_docs.py")
    gen = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(gen)
    found = set()
    for rel in gen.FILES:
        text = (root / rel).read_text(encoding="utf-8")
        blocks = gen.blocks_in(text)
        found |= set(blocks)
        for name, content in blocks.items():
            assert content == gen.BLOCKS[name](), f"{rel}: block {name!r} is stale: run `make docs`"
    assert found == set(gen.BLOCKS)
