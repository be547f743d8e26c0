"""stiffcal: measurement-pose selection for elasto-static (stiffness) calibration of serial robots.

After Wu, Klimchik, Pashkevich, Caro, Furet, "Optimality criteria for measurement poses selection in
calibration of robot stiffness parameters", ASME 2012 11th Biennial Conference on Engineering Systems Design
and Analysis (ESDA 2012), Nantes (the seed paper; equation numbers cited are theirs; CITATION.cff).

The public API (:mod:`stiffcal.api`; angles in degrees at this edge)::

    import stiffcal
    robot = stiffcal.load_robot("config/robots/paper_2r.yaml")
    res = stiffcal.design(robot, test_pose_deg=[60, 30], force_N=[0, -1], experiments=3)
    verdict = stiffcal.analyse_measurements(robot, "data/synthetic_paper_2r.csv")
    plan = stiffcal.plan_discrimination(robot, "data/synthetic_paper_2r.csv", experiments=6)

Names are imported on first use, so ``import stiffcal`` (and every workflow job) loads only what it needs.

The subpackages (docs/extending.md, "Where things live"): :mod:`stiffcal.model` (robot kinds, kinematics, the
elasto-static model, what a measurement sees, the criteria, loads, the cell), :mod:`stiffcal.planning` (the design
problem, plans, the certificate, the design cache, maps), :mod:`stiffcal.measured` (the measured-data contract, its
error model, the catalogue, the analysis, the discrimination plan, the calibrated model), :mod:`stiffcal.paper`,
:mod:`stiffcal.report`, :mod:`stiffcal.workflow` and :mod:`stiffcal.testing` (the simulator, reference solvers and
baselines of the tests and benchmarks; no production module imports it). The modules' flat paths of release 0.1
(``stiffcal.discrepancy``, ``stiffcal.truth``, ...) still import, as the same module objects, with a
DeprecationWarning (:data:`_MOVED`); they go in the next release.
"""

__version__ = "0.1.0"

_LAZY = {"load_robot": "model.robot", "Robot": "model.robot", "design": "api", "DesignResult": "api",
         "analyse_measurements": "api", "plan_discrimination": "api", "predict_deflection": "api",
         "compensate_path": "api", "plan_next_round": "api", "InputError": "errors", "Verdict": "measured.results",
         "DiscriminationPlan": "measured.results"}
__all__ = ["__version__", *_LAZY]

#: the modules' flat paths of release 0.1 -> where they live now (below the package); kept for one release
_MOVED = {
    "robot": "model.robot", "urdf": "model.urdf", "stiffness": "model.stiffness", "observation": "model.observation",
    "criteria": "model.criteria", "loads": "model.loads", "workcell": "model.workcell",
    "design": "planning.problem", "plans": "planning.plans", "certificate": "planning.certificate",
    "maps": "planning.maps", "_map_polynomials": "planning._map_polynomials", "_map_solver": "planning._map_solver",
    "designcache": "planning.designcache",
    "measurements": "measured.measurements", "catalogue": "model.catalogue", "discrepancy": "measured.discrepancy",
    "discrimination": "measured.discrimination", "errormodel": "measured.errormodel",
    "distributions": "measured.distributions", "calibrated": "measured.calibrated",
    "calibration": "model.calibration", "results": "measured.results",
    "reproduction": "paper.reproduction", "tables": "paper.tables", "plots": "report.plots",
    "pipeline": "workflow.pipeline", "config": "workflow.config", "archive": "workflow.archive",
    "codeversion": "workflow.codeversion", "study": "planning.study",
    "truth": "testing.truth", "reference": "testing.reference", "rates": "testing.rates",
    "_map_baseline": "testing._map_baseline",
}


def __getattr__(name: str):  # PEP 562: the names of _LAZY are imported on first use
    if name in _LAZY:
        import importlib

        value = getattr(importlib.import_module(f"{__name__}.{_LAZY[name]}"), name)
        globals()[name] = value
        return value
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def __dir__():
    return sorted(set(globals()) | set(_LAZY))


def _install_moved_paths() -> None:
    """``import stiffcal.<old>`` (a key of :data:`_MOVED`) gives the module at its new path, the same object
    (``sys.modules`` holds it under both names, so ``mock.patch("stiffcal.discrepancy.x")`` patches the module
    the code runs), with a DeprecationWarning naming the new path. ``stiffcal.design`` stays the API function:
    the package attribute is never set to the old ``design`` module."""
    import importlib
    import importlib.abc
    import importlib.util
    import sys
    import types
    import warnings

    prefix = __name__ + "."

    class _Moved(importlib.abc.MetaPathFinder, importlib.abc.Loader):
        def find_spec(self, fullname, path=None, target=None):
            if fullname.startswith(prefix) and fullname[len(prefix):] in _MOVED:
                return importlib.util.spec_from_loader(fullname, self)
            return None

        def create_module(self, spec):
            new = f"{prefix}{_MOVED[spec.name[len(prefix):]]}"
            warnings.warn(f"{spec.name} is now {new}; the old path goes in the next release", DeprecationWarning,
                          stacklevel=2)
            module = importlib.import_module(new)
            self._spec = module.__spec__
            return module

        def exec_module(self, module):
            module.__spec__ = self._spec  # the import system set the alias's spec on the real module: put it back

    class _Package(types.ModuleType):
        @property
        def design(self):
            from .api import design

            return design

        @design.setter
        def design(self, value):
            pass

    sys.meta_path.insert(0, _Moved())
    sys.modules[__name__].__class__ = _Package


_install_moved_paths()
