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
"""

__version__ = "0.1.0"

_LAZY = {"load_robot": "robot", "Robot": "robot", "design": "api", "DesignResult": "api",
         "analyse_measurements": "api", "plan_discrimination": "api", "predict_deflection": "api",
         "compensate_path": "api", "plan_next_round": "api", "InputError": "errors", "Verdict": "results",
         "DiscriminationPlan": "results"}
__all__ = ["__version__", *_LAZY]


def __getattr__(name: str):  # PEP 562: the names of _LAZY are imported on first use
    if name in _LAZY:
        import importlib

        value = getattr(importlib.import_module(f"{__name__}.{_LAZY[name]}"), name)
        globals()[name] = value
        return value
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def __dir__():
    return sorted(set(globals()) | set(_LAZY))


def _keep_design_function() -> None:
    """``stiffcal.design`` is the API function. The module ``stiffcal.design`` (single-pose search) has the same
    name, and importing it would set the package attribute to the module: this class keeps the function (the
    module stays importable as ``from stiffcal.design import ...``; ``sys.modules['stiffcal.design']``)."""
    import sys
    import types

    class _Package(types.ModuleType):
        @property
        def design(self):
            from .api import design

            return design

        @design.setter
        def design(self, value):
            pass

    sys.modules[__name__].__class__ = _Package


_keep_design_function()
