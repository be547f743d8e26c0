"""The limits of what stiffcal accepts: physical ranges of numeric inputs and bounds on sizes, in one place.

Every number a user gives (robot files, URDFs, command-line options, API arguments, the workflow config) is
checked against a physical range before any algebra, and every size that decides how much memory or time a
command needs is checked before anything is allocated; a value outside is refused with one message naming the
field, the bound and why (docs/contracts.md, "Limits"). The values:

Physical ranges
  * lengths (link lengths, DH ``a``/``d``, ``tool_m``, targets, URDF joint origins): ``|x| <=``
    :data:`MAX_LENGTH_M`; a planar link is at least :data:`MIN_LINK_M` long, and the measured point of any arm
    is at least :data:`MIN_LINK_M` from some joint axis (a smaller arm cannot be told from a point);
  * loads: every force component and hanging weight ``<=`` :data:`MAX_FORCE_N`, every moment component
    ``<=`` :data:`MAX_MOMENT_NM`; the load of a design (force and moment together) at least
    :data:`MIN_LOAD` in magnitude; a load the lab applies (``--loads``) at least the load-cell resolution
    (``--force-resolution-N``, default 0.5 N), below which it cannot be told from no load;
  * URDF joint axes: a direction whose length lies in [:data:`MIN_AXIS_NORM`, :data:`MAX_AXIS_NORM`]
    (never the zero vector); URDF rotations (``rpy``) at most :data:`MAX_RPY_RAD` in magnitude.

Sizes
  * joints of an arm: at most :data:`MAX_JOINTS` (every industrial and collaborative arm has at most 7; the
    design's searches grow exponentially with the joints: a 10-joint spatial arm needs about 40 s and
    1.8 GB, an 11-joint one more than 3 GB);
  * a URDF file: at most :data:`MAX_URDF_BYTES` and :data:`MAX_URDF_ELEMENTS` links and joints in all;
  * poses of a design (``--experiments``): at most :data:`MAX_DESIGN_EXPERIMENTS`; measurements of a
    discriminating plan: at most :data:`MAX_DISCRIMINATE_EXPERIMENTS` (its exchange grows as M^2: 100 take about
    a minute for a 2-joint arm, 1000 would take hours);
  * a load set (``--loads``): at most :data:`MAX_LOADS` loads (directions times magnitudes), each a candidate at
    every pose of the pool;
  * memory: every stiffcal command and workflow job runs with its address space capped at
    :func:`memory_cap_mb` MB (default :data:`DEFAULT_MAX_MEMORY_MB`, ``STIFFCAL_MAX_MEMORY_MB`` to change it):
    past it the job stops with one line instead of exhausting the machine.
"""

from __future__ import annotations

import os

#: longest length accepted anywhere [m] (link lengths, DH a and d, tool points, targets, URDF origins)
MAX_LENGTH_M = 1000.0
#: shortest planar link, and the smallest distance of the measured point from the joint axes, accepted [m]
MIN_LINK_M = 1e-6
#: a spatial arm's tool point or target farther from the tip frame than this many times the arm's own length (its
#: joint origins from the base, the tool left out) is refused: millimetres given as metres (a fresh user's tool_m
#: [100, 30, 0] on a 0.95 m arm was planned in silence)
TOOL_LENGTHS = 10.0
#: largest force component or hanging weight accepted [N] (10 MN: a thousand tonnes)
MAX_FORCE_N = 1e7
#: largest moment component accepted [N m]
MAX_MOMENT_NM = 1e7
#: smallest load (the norm of the force and moment components together) of a design [N, N m]
MIN_LOAD = 1e-6
#: measured data: the most rows of a measured-data CSV (its analysis grows linearly with the rows: 2 x 10^5 rows of
#: a 6-axis arm take about two minutes and 2.7 GB, benchmarks/bench_rows.py; a day's tracker log of 10^6 rows would
#: need more than the memory cap): average the replicates of a configuration and load, or analyse the log in parts
MAX_MEASURED_ROWS = 200_000
#: measured data: the most columns of a measured-data CSV (its own are a dozen or two; other columns are ignored)
MAX_MEASURED_COLUMNS = 1000
#: measured data: the longest pose_id [characters], a configuration's name (labels of megabytes only fill the memory
#: and the figures' axes)
MAX_LABEL_CHARS = 200
#: measured data: the RMS displacement [m] of the loaded rows below which the loads move nothing measurable (a
#: picometre, far below any tracker's resolution: zeros written for blanks, or a wrong unit)
MIN_DISPLACEMENT_M = 1e-12
#: measured data: the noise estimate over the RMS displacement below which the data have no noise in fact
#: (replicates that are exact copies of an average, or simulated data without noise, whose scatter is the round-off
#: of the fits: 1e-8 of the displacements is seen): every test would be infinitely confident. A lab's ratio is
#: 1e-3 and more (a tracker's micrometres against displacements of at most millimetres)
MIN_NOISE_RATIO = 1e-6
#: a URDF joint axis is a direction: its length must lie in [MIN_AXIS_NORM, MAX_AXIS_NORM]
MIN_AXIS_NORM = 1e-6
MAX_AXIS_NORM = 1e6
#: largest |roll|, |pitch|, |yaw| of a URDF origin accepted [rad] (a few turns)
MAX_RPY_RAD = 100.0

#: most joints of an arm (module docstring)
MAX_JOINTS = 10
#: largest URDF file read [bytes] (meshes are referenced, not embedded: real URDFs are far smaller)
MAX_URDF_BYTES = 10_000_000
#: most links and joints of a URDF, in all (the chain and everything off it)
MAX_URDF_ELEMENTS = 4000
#: most poses of a design (stiffcal design --experiments)
MAX_DESIGN_EXPERIMENTS = 1000
#: most measurements of a discriminating plan (stiffcal discriminate --experiments)
MAX_DISCRIMINATE_EXPERIMENTS = 100
#: most loads of a load set (--loads: directions times magnitudes, or forces)
MAX_LOADS = 64
#: most candidate poses read from a file (stiffcal design --candidates; the generated pools hold about 10^4), and
#: the largest such file [bytes]
MAX_CANDIDATES = 100_000
MAX_CANDIDATE_BYTES = 50_000_000

#: the address-space cap of a command or a workflow job [MB], unless STIFFCAL_MAX_MEMORY_MB says otherwise
DEFAULT_MAX_MEMORY_MB = 4096
MEMORY_VARIABLE = "STIFFCAL_MAX_MEMORY_MB"
#: the smallest cap accepted [MB]
MIN_MEMORY_MB = 1024


def memory_cap_mb() -> int | None:
    """The memory cap [MB] of this process: ``STIFFCAL_MAX_MEMORY_MB`` (0 or 'none': no cap) or
    :data:`DEFAULT_MAX_MEMORY_MB`. A value that is not a whole number is refused (InputError naming it)."""
    from .errors import InputError

    text = os.environ.get(MEMORY_VARIABLE, "").strip()
    if not text:
        return DEFAULT_MAX_MEMORY_MB
    if text.lower() in ("0", "none"):
        return None
    try:
        mb = int(text)
    except ValueError:
        mb = -1
    if mb < MIN_MEMORY_MB:
        raise InputError(f"expected a whole number of megabytes >= {MIN_MEMORY_MB} (the libraries alone map about "
                         f"600 MB), or 0 for no cap, got {text!r}", field=MEMORY_VARIABLE)
    return mb


def cap_memory() -> int | None:
    """Cap this process's address space (``RLIMIT_AS``) at :func:`memory_cap_mb` MB, never above a cap already
    set (a scheduler's); returns the cap in MB (None: no cap). An allocation past it raises MemoryError, which the
    command and the workflow report as one line (:func:`memory_message`)."""
    import resource

    mb = memory_cap_mb()
    if mb is None:
        return None
    want = mb * 1024 * 1024
    soft, hard = resource.getrlimit(resource.RLIMIT_AS)
    if hard != resource.RLIM_INFINITY:
        want = min(want, hard)
    if soft == resource.RLIM_INFINITY or soft > want:
        try:
            resource.setrlimit(resource.RLIMIT_AS, (want, hard))
        except (ValueError, OSError):  # pragma: no cover - a platform without RLIMIT_AS
            return None
    return min(want, soft if soft != resource.RLIM_INFINITY else want) // (1024 * 1024)


def memory_message() -> str:
    """The one line for a job stopped at the memory cap."""
    mb = memory_cap_mb()
    return (f"stopped at the memory cap of {mb} MB per job ({MEMORY_VARIABLE}; docs/contracts.md, 'Limits'): the "
            "input asks for more memory than that; make it smaller (fewer joints, poses, loads or grid points), or "
            f"raise the cap with {MEMORY_VARIABLE}=MB")
