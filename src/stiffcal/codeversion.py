"""Code versions of the workflow's steps, so that a change to library code reruns exactly the jobs whose
output it can change (docs/workflow.md, "When a job reruns").

Every rule declares ``params: code=code_version("<step>", ...)``, naming the functions of
:mod:`stiffcal.pipeline` it runs. The version is a hash of

* the source of those functions and of every module-level function and constant of ``pipeline.py`` they
  refer to (transitively), and
* the complete source of every ``stiffcal`` module they import (at module level or inside a function),
  and of every module those import, transitively.

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

PACKAGE = Path(__file__).resolve().parent


@lru_cache(maxsize=None)
def _source(module: str) -> tuple[str, ast.Module]:
    text = (PACKAGE / f"{module}.py").read_text(encoding="utf-8")
    return text, ast.parse(text)


def _is_module(name: str) -> bool:
    return (PACKAGE / f"{name}.py").is_file()


def imported_modules(node: ast.AST) -> set[str]:
    """The ``stiffcal`` modules imported anywhere inside ``node`` (relative or absolute imports)."""
    out: set[str] = set()
    for n in ast.walk(node):
        if isinstance(n, ast.ImportFrom):
            if n.level == 1 and n.module:
                out.add(n.module.split(".")[0])
            elif n.level == 1 or (n.level == 0 and n.module == "stiffcal"):
                out |= {a.name for a in n.names}
            elif n.level == 0 and n.module and n.module.startswith("stiffcal."):
                out.add(n.module.split(".")[1])
        elif isinstance(n, ast.Import):
            out |= {a.name.split(".")[1] for a in n.names if a.name.startswith("stiffcal.")}
    return {m for m in out if _is_module(m)}


@lru_cache(maxsize=None)
def _module_imports(module: str) -> frozenset[str]:
    """The ``stiffcal`` modules that ``module`` imports anywhere (parsed once per Snakefile parse)."""
    return frozenset(imported_modules(_source(module)[1]))


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
    return _definitions(_source("pipeline")[1])


@lru_cache(maxsize=None)
def _definition_uses(name: str) -> tuple[frozenset[str], frozenset[str]]:
    """(pipeline definitions that the definition ``name`` refers to, stiffcal modules it imports)."""
    defs = _pipeline_definitions()
    node = defs[name]
    refs = frozenset(n.id for n in ast.walk(node) if isinstance(n, ast.Name) and n.id in defs)
    return refs, frozenset(imported_modules(node))


def step_closure(steps) -> tuple[list[str], set[str]]:
    """(pipeline definitions used, stiffcal modules imported) by the pipeline functions ``steps``."""
    defs = _pipeline_definitions()
    missing = [s for s in steps if s not in defs]
    if missing:
        raise KeyError(f"stiffcal.pipeline has no step {missing[0]!r}")
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
    return sorted(used), module_closure(modules)


@lru_cache(maxsize=None)
def _segment(name: str) -> str:
    """The source text of the pipeline definition ``name`` (what ``ast.get_source_segment`` gives)."""
    text = _source("pipeline")[0]
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
    from .memo import JsonMemo, package_fingerprint

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


def _code_version(steps) -> str:
    used, modules = step_closure(steps)
    h = hashlib.sha256()
    for name in used:
        h.update(f"pipeline.{name}\0{_segment(name)}\0".encode())
    for m in sorted(modules):
        h.update(f"{m}\0{_source(m)[0]}\0".encode())
    return h.hexdigest()[:12]
