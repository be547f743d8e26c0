"""The package's layout (docs/extending.md, "Where things live"): the subpackages import only those before them,
nothing in production imports the test support (stiffcal.testing), and every flat module path of release 0.1 still
imports, as the very module at its new path, with a DeprecationWarning."""

import ast
import json
import subprocess
import sys
from pathlib import Path

import stiffcal
from stiffcal.workflow import codeversion

PACKAGE = Path(stiffcal.__file__).resolve().parent
#: the subpackages in their import order: each may import those before it, never one after it
ORDER = ["model", "planning", "paper", "report", "measured", "workflow"]


def _modules() -> dict[str, Path]:
    out = {}
    for path in sorted(PACKAGE.rglob("*.py")):
        parts = list(path.relative_to(PACKAGE).with_suffix("").parts)
        if parts[-1] == "__init__":
            parts = parts[:-1]
        if parts:
            out[".".join(parts)] = path
    return out


def _imports(module: str, path: Path) -> set[str]:
    """The stiffcal modules (dotted below the package) that any import statement of ``path`` runs, every import
    form resolved (:func:`stiffcal.workflow.codeversion.imported_modules`, tested on its own)."""
    return codeversion.imported_modules(ast.parse(path.read_text(encoding="utf-8")), module)


def test_no_production_module_imports_the_test_support_and_subpackages_import_only_those_before_them():
    bad = []
    for module, path in _modules().items():
        top = module.split(".")[0]
        if top == "testing":
            continue
        for m in _imports(module, path):
            dep = m.split(".")[0]
            if dep == "testing":
                bad.append(f"{module} imports the test support {m}")
            elif top in ORDER and dep in ORDER and ORDER.index(dep) > ORDER.index(top):
                bad.append(f"{module} ({top}) imports {m} ({dep}, later in {ORDER})")
            elif "." not in module and module not in ("api", "cli") and dep in ORDER:
                bad.append(f"the input and output layer's {module} imports {m}")
    assert not bad, "\n".join(bad)


def _run(code: str) -> dict:
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    return json.loads(out.stdout)


def test_importing_every_production_module_loads_nothing_of_the_test_support():
    production = [m for m in _modules() if not m.startswith("testing")]
    loaded = _run(f"""
import importlib, json, sys
for m in {production!r}:
    importlib.import_module("stiffcal." + m)
print(json.dumps(sorted(m for m in sys.modules if m.startswith("stiffcal.testing"))))
""")
    assert loaded == []


def test_every_old_flat_path_imports_the_module_at_its_new_path_with_a_deprecation_warning():
    moved = stiffcal._MOVED
    assert set(moved.values()) <= set(_modules())
    assert not set(moved) & set(_modules())  # an old path is never a module of its own
    report = _run(f"""
import importlib, json, warnings
import stiffcal
out = {{}}
for old, new in {moved!r}.items():
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        a = importlib.import_module("stiffcal." + old)
    b = importlib.import_module("stiffcal." + new)
    out[old] = [a is b, b.__name__, b.__spec__.name,
                [str(w.message) for w in caught if issubclass(w.category, DeprecationWarning)]]
from stiffcal.api import design
out["design is the API function"] = stiffcal.design is design
print(json.dumps(out))
""")
    assert report.pop("design is the API function") is True
    for old, (same, name, spec, warned) in report.items():
        new = "stiffcal." + moved[old]
        assert same and name == new and spec == new, old
        assert len(warned) == 1 and new in warned[0], (old, warned)


#: the longest function the package holds, docstring included [lines] (issue 26: long functions split into named
#: stages)
MAX_FUNCTION_LINES = 60


def test_no_function_of_the_package_is_longer_than_its_limit():
    """Every function and method of src/stiffcal (the generated _map_polynomials.py aside) is at most
    MAX_FUNCTION_LINES lines, its docstring included; the message names the longest."""
    long = []
    for name, path in _modules().items():
        if name.endswith("_map_polynomials"):
            continue
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                lines = node.end_lineno - node.lineno + 1
                if lines > MAX_FUNCTION_LINES:
                    long.append((lines, f"{name}.{node.name}"))
    assert not long, f"split into named stages: {sorted(long, reverse=True)}"
