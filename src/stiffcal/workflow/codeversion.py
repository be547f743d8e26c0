"""Code versions of the workflow's steps, so that a change to library code reruns exactly the jobs whose
output it can change (docs/workflow.md, "When a job reruns").

Every rule declares ``params: code=code_version("<step>", ...)``, naming the functions of
:mod:`stiffcal.workflow.pipeline` it runs. The version is a hash of

* the source of those functions and of every module-level function and constant of ``pipeline.py`` they
  refer to (transitively), and
* the complete source of every ``stiffcal`` module they import (at module level or inside a function),
  and of every module those import, transitively: modules of subpackages too (``stiffcal/a/b.py`` is
  ``a.b``, with ``a/__init__.py``), under every import form (``import stiffcal.a.b``, ``from stiffcal.a import
  b``, ``from stiffcal import name`` of a module or of a name the package imports on first use, relative
  imports of any level). The package's own ``__init__.py`` is left out: it only names what modules define.

Snakemake stores the parameters of every job it runs and reruns a job whose parameters changed (rerun
trigger ``params``, on by default), so editing ``plots.py`` reruns the figure jobs and the report, and
nothing else; editing a comment counts as a change (the hash is of the text). The analysis is static
(Python's ``ast``): nothing is imported, so it costs a few milliseconds when the Snakefile is parsed.
"""

from __future__ import annotations

import ast
import hashlib
import re
from functools import lru_cache
from pathlib import Path

PACKAGE = Path(__file__).resolve().parents[1]
#: the module whose functions are the workflow's steps
PIPELINE = "workflow.pipeline"


def _file(module: str) -> Path | None:
    """The source file of the ``stiffcal`` module ``module`` (a dotted name below the package, ``"plots"`` or
    ``"measured.verdict"``): ``<name>.py``, or a subpackage's ``__init__.py``; None if there is none."""
    base = PACKAGE.joinpath(*module.split("."))
    for path in (base.parent / f"{base.name}.py", base / "__init__.py"):
        if path.is_file():
            return path
    return None


@lru_cache(maxsize=None)
def _source(module: str) -> tuple[str, ast.Module]:
    path = _file(module)
    if path is None:
        raise KeyError(f"stiffcal has no module {module!r}")
    text = path.read_text(encoding="utf-8")
    return text, ast.parse(text)


def _is_module(name: str) -> bool:
    return bool(name) and _file(name) is not None


@lru_cache(maxsize=None)
def _lazy_names() -> dict[str, str]:
    """The package's names imported on first use (``_LAZY`` of ``stiffcal/__init__.py``: name -> module), so
    that ``from stiffcal import analyse_measurements`` counts as an import of the module behind it."""
    return _init_dict("_LAZY")


def _init_dict(variable: str) -> dict[str, str]:
    """The dict of strings assigned to ``variable`` in the package's ``__init__.py`` (read, not imported)."""
    init = PACKAGE / "__init__.py"
    if not init.is_file():
        return {}
    for node in ast.parse(init.read_text(encoding="utf-8")).body:
        if (isinstance(node, ast.Assign) and any(isinstance(t, ast.Name) and t.id == variable for t in node.targets)
                and isinstance(node.value, ast.Dict)):
            return {k.value: v.value for k, v in zip(node.value.keys, node.value.values)
                    if isinstance(k, ast.Constant) and isinstance(v, ast.Constant)}
    return {}


@lru_cache(maxsize=None)
def _moved() -> dict[str, str]:
    """The modules' old flat paths -> their paths now (``_MOVED`` of ``stiffcal/__init__.py``), so that an import by
    an old path (``from stiffcal import discrepancy``) counts as an import of the module it gives."""
    return _init_dict("_MOVED")


def _with_parents(parts: list[str]) -> set[str]:
    """A module and the subpackages above it (importing ``a.b.c`` runs ``a/__init__.py`` and ``a/b/__init__.py``);
    the package's own ``__init__.py``, which only names what the modules define, is left out."""
    return {".".join(parts[:i]) for i in range(1, len(parts) + 1)}


def _imported_by(n: ast.Import | ast.ImportFrom, module: str) -> set[str]:
    """The ``stiffcal`` modules (dotted names below the package) that the import statement ``n`` of ``module``
    runs, for every import form: ``import stiffcal.a.b``, ``from stiffcal.a import b``, ``from stiffcal import
    name`` (a module, or a name of ``_LAZY``), and relative imports of any level; a module's old flat path
    (``_MOVED``) counts as the module it gives."""
    out = _imported_by_path(n, module)
    return out.union(*(_with_parents(_moved()[m].split(".")) for m in out if m in _moved()))


def _imported_by_path(n: ast.Import | ast.ImportFrom, module: str) -> set[str]:
    """:func:`_imported_by` before the old paths are followed."""
    if isinstance(n, ast.Import):
        return set().union(*(_with_parents(a.name.split(".")[1:]) for a in n.names if a.name.startswith("stiffcal.")))
    if n.level:
        here, path = module.split("."), _file(module)
        package = here if path is not None and path.name == "__init__.py" else here[:-1]
        if n.level - 1 > len(package):
            return set()
        base = package[: len(package) - (n.level - 1)]
    elif n.module == "stiffcal" or (n.module or "").startswith("stiffcal."):
        base = []
        n = ast.ImportFrom(module=".".join(n.module.split(".")[1:]) or None, names=n.names, level=0)
    else:
        return set()
    target = base + (n.module.split(".") if n.module else [])
    out = _with_parents(target)
    for a in n.names:
        out |= _with_parents(target + [a.name])
        if not target and a.name in _lazy_names():
            out |= _with_parents(_lazy_names()[a.name].split("."))
    return out


def imported_modules(node: ast.AST, module: str = PIPELINE) -> set[str]:
    """The ``stiffcal`` modules imported anywhere inside ``node`` of the module ``module`` (every import form,
    :func:`_imported_by`), as dotted names below the package."""
    out: set[str] = set()
    for n in ast.walk(node):
        if isinstance(n, (ast.Import, ast.ImportFrom)):
            out |= _imported_by(n, module)
    return {m for m in out if _is_module(m)}


@lru_cache(maxsize=None)
def _module_imports(module: str) -> frozenset[str]:
    """The ``stiffcal`` modules that ``module`` imports anywhere (parsed once per Snakefile parse)."""
    return frozenset(imported_modules(_source(module)[1], module))


def module_closure(modules) -> set[str]:
    """``modules`` and every ``stiffcal`` module they import, transitively."""
    seen: set[str] = set()
    todo = list(modules)
    while todo:
        m = todo.pop()
        if m not in seen:
            seen.add(m)
            todo += _module_imports(m)
    return seen


def _definitions(tree: ast.Module) -> dict[str, ast.AST]:
    """Module-level functions, classes and assigned names of a module: name -> node."""
    out: dict[str, ast.AST] = {}
    for node in tree.body:
        if isinstance(node, (ast.FunctionDef, ast.ClassDef)):
            out[node.name] = node
        elif isinstance(node, (ast.Assign, ast.AnnAssign)):
            targets = node.targets if isinstance(node, ast.Assign) else [node.target]
            out |= {t.id: node for t in targets if isinstance(t, ast.Name)}
    return out


@lru_cache(maxsize=None)
def _pipeline_definitions() -> dict[str, ast.AST]:
    return _definitions(_source(PIPELINE)[1])


@lru_cache(maxsize=None)
def _pipeline_imports() -> dict[str, frozenset[str]]:
    """The names that module-level imports of the pipeline bind -> the ``stiffcal`` modules behind each."""
    out: dict[str, frozenset[str]] = {}
    for node in _source(PIPELINE)[1].body:
        if isinstance(node, (ast.Import, ast.ImportFrom)):
            for a in node.names:
                one = ast.Import(names=[a]) if isinstance(node, ast.Import) else ast.ImportFrom(
                    module=node.module, names=[a], level=node.level)
                bound = a.asname or a.name.split(".")[0]
                out[bound] = out.get(bound, frozenset()) | {m for m in _imported_by(one, PIPELINE) if _is_module(m)}
    return out


@lru_cache(maxsize=None)
def _definition_uses(name: str) -> tuple[frozenset[str], frozenset[str]]:
    """(pipeline definitions that the definition ``name`` refers to, stiffcal modules it imports, inside it or
    through a name a module-level import binds)."""
    defs, bound = _pipeline_definitions(), _pipeline_imports()
    node = defs[name]
    names = {n.id for n in ast.walk(node) if isinstance(n, ast.Name)}
    through = set().union(*(bound[n] for n in names if n in bound))
    return frozenset(names & defs.keys()), frozenset(imported_modules(node, PIPELINE) | through)


def step_closure(steps) -> tuple[list[str], set[str]]:
    """(pipeline definitions used, stiffcal modules imported) by the pipeline functions ``steps`` (with the packages
    above the pipeline module, whose ``__init__.py`` importing it runs)."""
    defs = _pipeline_definitions()
    missing = [s for s in steps if s not in defs]
    if missing:
        raise KeyError(f"stiffcal.{PIPELINE} has no step {missing[0]!r}")
    used: set[str] = set()
    modules: set[str] = set()
    todo = list(steps)
    while todo:
        name = todo.pop()
        if name in used:
            continue
        used.add(name)
        refs, imported = _definition_uses(name)
        modules |= imported
        todo += [n for n in refs if n not in used]
    packages = _with_parents(PIPELINE.split(".")[:-1])  # importing the pipeline runs its packages' __init__ too
    return sorted(used), module_closure(modules | {m for m in packages if _is_module(m)})


@lru_cache(maxsize=None)
def _segment(name: str) -> str:
    """The source text of the pipeline definition ``name`` (what ``ast.get_source_segment`` gives)."""
    text = _source(PIPELINE)[0]
    node = _pipeline_definitions()[name]
    lines = _lines(text)
    first, last = node.lineno - 1, node.end_lineno - 1
    if first == last:
        return lines[first].encode()[node.col_offset:node.end_col_offset].decode()
    return "".join([lines[first].encode()[node.col_offset:].decode(), *lines[first + 1:last],
                    lines[last].encode()[:node.end_col_offset].decode()])


@lru_cache(maxsize=None)
def _lines(text: str) -> list[str]:
    """``text`` split after every line end (``\\r\\n``, ``\\r`` or ``\\n``, as Python's parser counts lines)."""
    return re.findall(r"[^\r\n]*(?:\r\n|\r|\n)|[^\r\n]+$", text)


#: the workflow's memo of code versions (:func:`remember_code_versions`), or None
_MEMO = None


def remember_code_versions(path) -> None:
    """Keep the code versions in the JSON file ``path`` between runs, under the package's source
    (:func:`stiffcal.memo.package_fingerprint`): a rerun with no library edit reads them instead of parsing the
    package (the workflow: ``.snakemake/stiffcal/code-versions.json``); any edit starts the file afresh."""
    from ..memo import JsonMemo, package_fingerprint

    global _MEMO
    _MEMO = JsonMemo(path, package_fingerprint())
    code_version.cache_clear()


@lru_cache(maxsize=None)
def code_version(*steps: str) -> str:
    """12 hex digits of SHA-256 over the code that the pipeline functions ``steps`` run (module docstring)."""
    if _MEMO is None:
        return _code_version(steps)
    key = ",".join(steps)
    found = _MEMO.read().get(key)
    if not (isinstance(found, str) and re.fullmatch(r"[0-9a-f]{12}", found)):
        found = _code_version(steps)
        _MEMO.write({**_MEMO.read(), key: found})
    return found


def forget() -> None:
    """Drop every parsed source and derived version (after :data:`PACKAGE` or a source file changed)."""
    for f in (_source, _lazy_names, _moved, _module_imports, _pipeline_definitions, _pipeline_imports, _definition_uses,
              _segment, _lines, code_version):
        f.cache_clear()


def _code_version(steps) -> str:
    used, modules = step_closure(steps)
    h = hashlib.sha256()
    for name in used:
        h.update(f"pipeline.{name}\0{_segment(name)}\0".encode())
    for m in sorted(modules):
        h.update(f"{m}\0{_source(m)[0]}\0".encode())
    return h.hexdigest()[:12]
