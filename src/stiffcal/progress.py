"""Progress of long jobs, wherever stderr goes: a bar on a terminal, a line every few seconds otherwise (a log
file, a pipe, a scheduler's output), nothing when quiet. Reusable by every command and step:

>>> from stiffcal.progress import Progress
>>> with Progress("discrepancy", stages=[("reading", 1.0), ("fits", 20.0)]) as p:   # doctest: +SKIP
...     read()
...     p.advance("fits")            # the next stage: its estimated seconds give the estimate of what is left
...     for k in p.steps(range(500), "fits"):   # or count steps within a stage (the estimate follows their rate)
...         fit(k)

Lines look like ``[stiffcal 14:03:12] design: plan of 17 poses (stage 3/3), 1 min 05 s elapsed, about 40 s
left (estimate)``. The first comes after :func:`interval_s` seconds (default 5; ``STIFFCAL_PROGRESS_S``
changes it), so a short job prints nothing; a job whose estimate is a minute or more says so at once. Only the
innermost running Progress prints (a command-wide heartbeat stays silent while a step reports its own).
``enabled=False`` (``--quiet``) turns it off, and every Progress inside it left to its default.
"""

from __future__ import annotations

import os
import sys
import threading
import time

#: seconds between two progress lines off a terminal, unless STIFFCAL_PROGRESS_S says otherwise
DEFAULT_INTERVAL_S = 5.0
#: a job whose estimate is at least this long [s] says so when it starts
ANNOUNCE_S = 60.0

_ACTIVE: list["Progress"] = []
#: progresses entered disabled (``--quiet``): while one runs, a progress inside it left to its default is silent too
_SILENT: list["Progress"] = []
_LOCK = threading.Lock()


def interval_s() -> float:
    """Seconds between progress lines: ``STIFFCAL_PROGRESS_S`` (a number > 0) or :data:`DEFAULT_INTERVAL_S`."""
    try:
        v = float(os.environ.get("STIFFCAL_PROGRESS_S", DEFAULT_INTERVAL_S))
    except ValueError:
        return DEFAULT_INTERVAL_S
    return v if v > 0 else DEFAULT_INTERVAL_S


def duration(seconds: float) -> str:
    """``75`` -> ``'1 min 15 s'``, ``4000`` -> ``'1 h 07 min'``, ``8.2`` -> ``'8 s'``."""
    s = int(round(max(seconds, 0.0)))
    if s < 60:
        return f"{s} s"
    if s < 3600:
        return f"{s // 60} min {s % 60:02d} s"
    return f"{s // 3600} h {s % 3600 // 60:02d} min"


class Progress:
    """Progress of one job on ``stream`` (default stderr).

    label: what runs ('design'); stages: ``[(name, estimated seconds), ...]`` in order (the estimate of what is
    left is the sum of the stages to come, scaled by how the finished ones compared with their estimates), or
    None for a job without stages (the lines then say how long it has run); enabled: None or True shows it
    (a bar when ``stream`` is a terminal, lines otherwise), False nothing; interval: seconds between lines
    (:func:`interval_s`); clock: the time in seconds (``time.monotonic``)."""

    def __init__(self, label: str, stages=None, *, enabled: bool | None = None, stream=None,
                 interval: float | None = None, clock=time.monotonic):
        self.label = label
        self.clock = clock
        self.stages = [(str(n), max(float(w), 1e-3)) for n, w in (stages or [])]
        self.stream = sys.stderr if stream is None else stream
        with _LOCK:  # inside a quiet job (a command run with --quiet) a step's own progress is quiet too
            self.enabled = enabled is True or (enabled is None and not _SILENT)
        self.interval = interval_s() if interval is None else float(interval)
        self.index = 0  # the stage running
        self.steps_done = self.steps_total = 0
        self.t0 = self.stage_t0 = clock()
        self.finished_estimate = self.finished_actual = 0.0
        self._stop = threading.Event()
        self._thread = None
        self._bar = None
        self.lines = 0

    # --- the state ------------------------------------------------------------------------------------------
    @property
    def stage(self) -> str:
        return self.stages[self.index][0] if self.index < len(self.stages) else ""

    def remaining_s(self) -> tuple[float | None, bool]:
        """(estimated seconds left, or None without an estimate (no stages, no step counts); whether the current
        stage has run past its estimate, when what is left counts only the stages after it). The stages to come
        are scaled by how the stages so far compared with their estimates."""
        now = self.clock()
        in_stage = now - self.stage_t0
        counted = self.steps_total and self.steps_done
        current = in_stage / self.steps_done * (self.steps_total - self.steps_done) if counted else None
        if not self.stages:
            return current, False
        if self.index >= len(self.stages):
            return 0.0, False
        est = self.stages[self.index][1]
        over = current is None and in_stage > est
        if over:
            speed = (self.finished_actual + in_stage) / (self.finished_estimate + est)
        else:
            speed = self.finished_actual / self.finished_estimate if self.finished_estimate else 1.0
        later = sum(w for _, w in self.stages[self.index + 1:]) * speed
        if over:
            return later, True
        return later + (current if current is not None else max(est * speed - in_stage, 0.0)), False

    def estimate_s(self) -> float:
        """The whole job's estimate [s] (the stages' estimates)."""
        return sum(w for _, w in self.stages)

    def line(self) -> str:
        """The progress line for now."""
        elapsed = self.clock() - self.t0
        what = self.label
        if self.stages and self.index < len(self.stages):
            what += f": {self.stage} (stage {self.index + 1}/{len(self.stages)})"
        if self.steps_total:
            what += f" {self.steps_done}/{self.steps_total}"
        text = f"[stiffcal {time.strftime('%H:%M:%S')}] {what}, {duration(elapsed)} elapsed"
        left, over = self.remaining_s()
        if over:
            text += ", this stage taking longer than estimated" + (
                f"; about {duration(left)} left after it (estimate)" if left >= 0.5 else "")
        elif left is not None:
            text += f", about {duration(left)} left (estimate)"
        return text

    # --- reporting ------------------------------------------------------------------------------------------
    def advance(self, stage: str | None = None) -> None:
        """The current stage is done; the next one (named ``stage`` if given, which must be one of ``stages``)
        begins."""
        now = self.clock()
        if self.index < len(self.stages):
            self.finished_estimate += self.stages[self.index][1]
            self.finished_actual += now - self.stage_t0
        names = [n for n, _ in self.stages]
        self.index = names.index(stage, self.index) if stage in names[self.index:] else self.index + 1
        self.stage_t0, self.steps_done, self.steps_total = now, 0, 0
        self._refresh_bar()

    def step(self, done: int, total: int) -> None:
        """``done`` of ``total`` steps of the current stage are done (a callback ``progress(done, total)``)."""
        self.steps_done, self.steps_total = int(done), int(total)
        self._refresh_bar()

    def steps(self, iterable, stage: str | None = None):
        """Iterate over ``iterable`` (with a length), counting its items as the steps of the current stage."""
        items = list(iterable) if not hasattr(iterable, "__len__") else iterable
        total = len(items)
        for k, item in enumerate(items):
            self.step(k, total)
            yield item
        self.step(total, total)

    # --- the thread -----------------------------------------------------------------------------------------
    def _is_tty(self) -> bool:
        try:
            return self.stream.isatty()
        except (AttributeError, ValueError):
            return False

    def _print(self, text: str) -> None:
        try:
            print(text, file=self.stream, flush=True)
            self.lines += 1
        except (OSError, ValueError):  # the stream went away (a closed pipe): progress is not worth an error
            self._stop.set()

    def _refresh_bar(self) -> None:
        if self._bar is not None:
            with _LOCK:
                left, over = self.remaining_s()
                self._bar.set_description_str(f"{self.label}: {self.stage}" if self.stage else self.label,
                                              refresh=False)
                self._bar.n = self.index if self.stages else self.steps_done
                self._bar.set_postfix_str("" if left is None else f"about {duration(left)} left"
                                          + (" after this stage" if over else ""), refresh=False)
                self._bar.refresh()

    def _new_bar(self):
        tqdm = _tqdm()
        return tqdm(total=len(self.stages) or None, file=self.stream, leave=False, unit="stage",
                    bar_format="{desc}: {n_fmt}/{total_fmt} stages {bar} {elapsed} {postfix}"
                    if self.stages else "{desc}: {elapsed} elapsed")

    def _run(self) -> None:
        tty = self._is_tty()
        period = 1.0 if tty else self.interval
        while not self._stop.wait(period):
            with _LOCK:
                innermost = bool(_ACTIVE) and _ACTIVE[-1] is self
            if tty and not self.stages:  # a heartbeat's bar only while no inner progress shows its own
                with _LOCK:
                    if innermost and self._bar is None:
                        self._bar = self._new_bar()
                    elif not innermost and self._bar is not None:
                        self._bar.close()
                        self._bar = None
            if not innermost:
                continue
            if tty:
                self._refresh_bar()
            else:
                self._print(self.line())

    def __enter__(self) -> "Progress":
        if not self.enabled:
            with _LOCK:
                _SILENT.append(self)
            return self
        with _LOCK:
            if _ACTIVE:  # a step inside a command: its elapsed time is the command's
                self.t0 = min(self.t0, _ACTIVE[0].t0)
            _ACTIVE.append(self)
        if self._is_tty():
            _tqdm()  # imported here, not by the reporting thread (see _tqdm)
            if self.stages:  # a heartbeat's bar comes after a second, if nothing inner shows one (_run)
                self._bar = self._new_bar()
                self._refresh_bar()
        elif self.estimate_s() >= ANNOUNCE_S:
            self._print(f"[stiffcal {time.strftime('%H:%M:%S')}] {self.label}: estimated about "
                        f"{duration(self.estimate_s())}, a progress line every {duration(self.interval)}")
        self._thread = threading.Thread(target=self._run, name=f"stiffcal-progress-{self.label}", daemon=True)
        self._thread.start()
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def close(self) -> None:
        """Stop reporting (the bar is removed; no further lines)."""
        self._stop.set()
        if self._thread is not None:
            self._thread.join()
            self._thread = None
        with _LOCK:
            if self in _ACTIVE:
                _ACTIVE.remove(self)
            if self in _SILENT:
                _SILENT.remove(self)
        if self._bar is not None:
            self._bar.close()
            self._bar = None


def _tqdm():
    """tqdm's bar class with its write lock made. Called first on the thread that enters a progress, before the
    reporting thread starts: an import of an extension module there (tqdm's lock imports ``_multiprocessing``)
    takes the dynamic loader's lock while holding the GIL, and deadlocks against the main thread when it
    walks the loaded libraries (threadpoolctl's ``dl_iterate_phdr``, whose Python callback waits for the GIL:
    seen as a hung ``stiffcal design`` on a terminal)."""
    from tqdm.auto import tqdm

    tqdm.get_lock()
    return tqdm


def write(text: str, stream=None) -> None:
    """Print a line (a note, a warning) on ``stream`` (default stderr) without mixing it into a progress bar
    shown there: the bars are cleared first and drawn again after it."""
    stream = sys.stderr if stream is None else stream
    with _LOCK:
        bars = [p._bar for p in _ACTIVE if p._bar is not None and p.stream is stream]
        for bar in bars:
            bar.clear()
        print(text, file=stream, flush=True)
        for bar in bars:
            bar.refresh()
