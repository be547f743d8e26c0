"""Robot files for real arms whose descriptions nobody here wrote: the URDFs, collision meshes and SRDFs of the
``example-robot-data`` package (pinned in requirements-test.lock; the product does not need it), mounted on the
floor with self-collision on. Used by tests/test_workcell.py and benchmarks/bench_workcell.py."""

from __future__ import annotations

from pathlib import Path

#: name -> (URDF, SRDF or None, base frame, tip frame, tool point in the tip frame [m], a test pose [deg],
#: test force [N])
ARMS = {
    "ur10": ("ur_description/urdf/ur10_robot.urdf", None, "base_link", "tool0", [0.05, 0.0, 0.05],
             [20, -100, 90, -80, -90, 30], [300, -200, -500]),
    "panda": ("panda_description/urdf/panda.urdf", "panda_description/srdf/panda.srdf", "panda_link0", "panda_hand",
              [0.05, 0.0, 0.1], [10, 20, 0, -120, 0, 140, 45], [50, -40, -80]),
    "jaco2": ("kinova_description/robots/kinova.urdf", "kinova_description/srdf/kinova.srdf", "base",
              "j2s6s200_end_effector", [0.05, 0.0, 0.05], [0, 180, 90, 0, 120, 0], [20, -15, -30]),
}


def robots_dir() -> Path | None:
    """The ``robots`` directory of example-robot-data, or None when the package is not installed."""
    try:
        import example_robot_data as erd
    except ImportError:
        return None
    d = Path(erd.getModelPath("ur_description/urdf/ur10_robot.urdf")).resolve()
    return d if (d / "ur_description").is_dir() else None


def write_robot_file(name: str, directory: Path, floor_m: float = 0.0, clearance_m: float = 0.02,
                     extra: str = "") -> Path:
    """A robot file for arm ``name`` (:data:`ARMS`) standing on the floor (floor_m) with self-collision, written
    into ``directory``; returns its path."""
    urdf, srdf, base, tip, tool, _, _ = ARMS[name]
    root = robots_dir()
    lines = [f"name: {name}-cell", "kind: urdf", f"urdf: {root / urdf}", f"base_frame: {base}", f"tip_frame: {tip}",
             f"tool_m: {tool}", "cell:", f"  floor_m: {floor_m}", f"  clearance_m: {clearance_m}",
             "  self_collision: true"]
    if srdf:
        lines.append(f"  srdf: {root / srdf}")
    path = Path(directory) / f"{name}.yaml"
    path.write_text("\n".join(lines) + "\n" + extra, encoding="utf-8")
    return path
