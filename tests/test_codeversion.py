"""Code versions follow the code a workflow step runs wherever it lives (stiffcal.workflow.codeversion): modules
moved into subpackages and every import form, so that moving a module never drops it out of the versions (an edit to
it must still rerun the jobs that use it)."""

import textwrap
from pathlib import Path

import pytest

from stiffcal.workflow import codeversion

#: a package laid out with subpackages and every import form; each step reaches one module by one form
FILES = {
    "__init__.py": '_LAZY = {"lazy_name": "sub.lazy"}\n_MOVED = {"flat": "other.flatmoved"}\n',
    "workflow/__init__.py": "",
    "workflow/pipeline.py": """
        from __future__ import annotations

        from ..top import bound

        def step_relative():
            from ..sub.moved import f
            return f()

        def step_absolute():
            import stiffcal.deep.inner.mod2
            return stiffcal.deep.inner.mod2

        def step_lazy():
            from stiffcal import lazy_name
            return lazy_name

        def step_from_package():
            from stiffcal.other import thing
            return thing

        def step_bound():
            return bound.x

        def step_old_path():
            from stiffcal import flat
            return flat

        def step_nothing():
            return 1
        """,
    "top/__init__.py": "",
    "top/bound.py": "x = 1\n",
    "sub/__init__.py": "",
    "sub/moved.py": "from ..leaf import g\n\ndef f():\n    return g()\n",
    "sub/lazy.py": "lazy_name = 1\n",
    "leaf.py": "def g():\n    return 2\n",
    "deep/__init__.py": "",
    "deep/inner/__init__.py": "from . import mod2\n",
    "deep/inner/mod2.py": "y = 2\n",
    "other/__init__.py": "",
    "other/thing.py": "z = 3\n",
    "other/flatmoved.py": "w = 4\n",
}
STEPS = ("step_relative", "step_absolute", "step_lazy", "step_from_package", "step_bound", "step_old_path",
         "step_nothing")
#: what an edit of each file must rerun (the parent packages' __init__ run on import too)
REACHES = {
    "sub/moved.py": {"step_relative"}, "leaf.py": {"step_relative"}, "sub/__init__.py": {"step_relative", "step_lazy"},
    "deep/inner/mod2.py": {"step_absolute"}, "deep/inner/__init__.py": {"step_absolute"},
    "deep/__init__.py": {"step_absolute"}, "sub/lazy.py": {"step_lazy"}, "other/thing.py": {"step_from_package"},
    "other/__init__.py": {"step_from_package", "step_old_path"}, "top/bound.py": {"step_bound"},
    "top/__init__.py": {"step_bound"}, "other/flatmoved.py": {"step_old_path"}, "workflow/__init__.py": set(STEPS),
}


@pytest.fixture
def package(tmp_path, monkeypatch) -> Path:
    root = tmp_path / "stiffcal"
    for name, text in FILES.items():
        (root / name).parent.mkdir(parents=True, exist_ok=True)
        (root / name).write_text(textwrap.dedent(text).lstrip(), encoding="utf-8")
    monkeypatch.setattr(codeversion, "PACKAGE", root)
    monkeypatch.setattr(codeversion, "_MEMO", None)
    codeversion.forget()
    yield root
    codeversion.forget()


def _versions() -> dict[str, str]:
    codeversion.forget()
    return {s: codeversion.code_version(s) for s in STEPS}


@pytest.mark.parametrize("edited", sorted(REACHES))
def test_an_edit_to_a_module_in_a_subpackage_reruns_exactly_the_steps_that_import_it(package, edited):
    before = _versions()
    path = package / edited
    path.write_text(path.read_text(encoding="utf-8") + "# an edit\n", encoding="utf-8")
    after = _versions()
    assert {s for s in STEPS if after[s] != before[s]} == REACHES[edited]


def test_each_import_form_resolves_to_the_module_and_its_parent_packages(package):
    closures = {s: codeversion.step_closure([s])[1] for s in STEPS}
    assert all("workflow" in closures[s] for s in STEPS)  # the pipeline's own package runs on every import of it
    modules = {s: closures[s] - {"workflow"} for s in STEPS}
    assert modules["step_relative"] == {"sub", "sub.moved", "leaf"}
    assert modules["step_absolute"] == {"deep", "deep.inner", "deep.inner.mod2"}
    assert modules["step_lazy"] == {"sub", "sub.lazy"}
    assert modules["step_from_package"] == {"other", "other.thing"}
    assert modules["step_bound"] == {"top", "top.bound"}
    assert modules["step_old_path"] == {"other", "other.flatmoved"}  # a flat path of _MOVED, as the module it gives


def test_the_real_package_closure_holds_every_module_a_step_imports():
    """On the real package: the discrepancy step's closure holds the analysis and what it imports."""
    codeversion.forget()
    modules = codeversion.step_closure(["discrepancy"])[1]
    assert {"measured.discrepancy", "measured.errormodel", "measured.measurements", "model.robot"} <= modules
    assert not any(m == "testing" or m.startswith("testing.") for m in modules)  # the simulator is not production code
    assert all(codeversion._file(m) is not None for m in modules)


def test_the_measured_data_steps_do_not_depend_on_the_maps():
    """A fresh user edited a maps-only module and saw every discrepancy and discriminate job rerun (the data set's
    test pose came from the config module, which imports the maps); docs/workflow.md says such an edit reruns the
    map jobs, the comparison and the report."""
    codeversion.forget()
    for step in ("discrepancy", "discriminate"):
        modules = codeversion.step_closure([step])[1]
        assert not {"planning.maps", "planning._map_solver", "workflow.config"} & modules, step
