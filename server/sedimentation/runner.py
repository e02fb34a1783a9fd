"""The live particle-sedimentation simulation behind the console's sedimentation view.

A :class:`SedimentationRunner` owns one moving scene (``shared.broadphase.workloads``) and one
many-body detector (``shared.broadphase.make_detector``). A background thread steps the scene
and runs the detector on every frame; only the detector call is timed, because the thesis's
FPS (chapter 5) is checks per second of *detection* time, not of the whole loop. The rolling
FPS is frames / summed detection time over the last :data:`FPS_WINDOW` frames.

The simulation is paced to at most ``steps_hz`` frames per second (so bodies move at a steady
on-screen speed whichever method runs), and a second thread hands :class:`SedimentationSnapshot`
objects to subscribers (the 3D view) at most ``draw_hz`` times per second, independently: a slow
subscriber drops pictures, never frames or detection time. Settings changes are validated in
the caller's thread (``InputError`` / ``UnknownNameError``) and applied under the runner's lock,
that is between two frames.
"""

from __future__ import annotations

import logging
import math
import threading
import time
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass, replace

import numpy as np
from pydantic import BaseModel, ConfigDict, Field

from shared.broadphase import METHODS, make_detector
from shared.broadphase.workloads import KINDS, THESIS_DENSITY, THESIS_SPEED, Scene, make_scene
from shared.errors import InputError, UnknownNameError

log = logging.getLogger(__name__)

#: Frames in the rolling FPS figure.
FPS_WINDOW = 60
#: Fewest bodies a scene may have (a pair needs two).
MIN_BODIES = 2
#: Brute force is O(N^2): more bodies would stall the view for seconds per frame.
BRUTE_MAX_BODIES = 3000
#: Largest SPEED (length units per frame); the thesis's Table 5.3 goes to 12.8.
MAX_SPEED = 16.0
#: Density bounds (bodies per unit volume; the thesis uses 0.0005). Above the upper bound unit
#: spheres would overlap several neighbours each and the scene stops being a suspension.
MIN_DENSITY, MAX_DENSITY = 1e-6, 0.05
#: Points per second the published pictures may carry: large scenes are drawn less often, so
#: the browser link is not flooded (200,000 bodies: 10 pictures per second).
MAX_POINTS_PER_S = 2_000_000
#: While paused, the current frame is published again this often (s).
PAUSED_PICTURE_S = 0.5
#: Shortest pause between two frames (s), so other threads get the GIL.
MIN_GAP_S = 0.001


@dataclass(frozen=True)
class SedimentationSettings:
    """What the operator chooses. ``speed`` is the thesis's SPEED (length units per frame),
    ``density`` = N / L^3 with unit-radius spheres."""

    method: str = "usscd"
    n: int = 2000
    speed: float = THESIS_SPEED
    kind: str = "uniform"
    density: float = THESIS_DENSITY
    seed: int = 0
    paused: bool = False


@dataclass(frozen=True)
class SedimentationSnapshot:
    """One simulated frame as the view draws it. Arrays are private copies (read-only use).

    ``centres`` (N, 3) and ``radii`` (N,) are the bodies exactly as the detector saw them,
    ``pairs`` (K, 2) its answer, ``colliding`` (N,) bool marks bodies in at least one pair;
    ``size`` is the cube side L (the cube is ``[0, L]^3``)."""

    settings: SedimentationSettings
    frame: int
    size: float
    fps: float
    steps_per_s: float
    centres: np.ndarray
    radii: np.ndarray
    pairs: np.ndarray
    colliding: np.ndarray

    @property
    def n_pairs(self) -> int:
        return int(self.pairs.shape[0])


class SedimentationState(BaseModel):
    """The runner's current settings and figures (``GET /api/sedimentation``)."""

    method: str = Field(description="broadphase method running")
    n: int = Field(description="number of bodies N")
    speed: float = Field(description="SPEED: distance each body moves per frame (sphere radius = 1)")
    kind: str = Field(description="scene kind: uniform, gaussian (clusters) or sediment (floor layer)")
    density: float = Field(description="N / L^3, bodies per unit volume")
    seed: int
    paused: bool
    size: float = Field(description="cube side L")
    frame: int = Field(description="frames simulated since the scene was (re)built")
    fps: float = Field(description="detection FPS: frames per second of detection time, rolling")
    pairs: int = Field(description="overlapping pairs in the latest frame")
    steps_per_s: float = Field(description="frames simulated per second of wall time")
    methods: list[str]
    kinds: list[str]
    max_n: int


class SedimentationChange(BaseModel):
    """A settings change (``PUT /api/sedimentation``): only the fields given change."""

    model_config = ConfigDict(extra="forbid")

    method: str | None = None
    n: int | None = Field(None, description="number of bodies N")
    speed: float | None = Field(None, description="SPEED, length units per frame (>= 0)")
    kind: str | None = None
    density: float | None = None
    seed: int | None = None
    paused: bool | None = None


def _as_int(name: str, value: object) -> int:
    if isinstance(value, bool):
        raise InputError(f"{name} must be a whole number, got {value!r}")
    try:
        f = float(value)  # type: ignore[arg-type]
    except (TypeError, ValueError):
        raise InputError(f"{name} must be a whole number, got {value!r}") from None
    if not math.isfinite(f) or f != int(f):
        raise InputError(f"{name} must be a whole number, got {value!r}")
    return int(f)


def _as_float(name: str, value: object) -> float:
    try:
        f = float(value)  # type: ignore[arg-type]
    except (TypeError, ValueError):
        raise InputError(f"{name} must be a number, got {value!r}") from None
    if not math.isfinite(f):
        raise InputError(f"{name} must be finite, got {value!r}")
    return f


def validate_settings(s: SedimentationSettings, max_n: int) -> SedimentationSettings:
    """Check every field; return the settings with numbers normalised to int/float."""
    if s.method not in METHODS:
        raise UnknownNameError("broadphase method", str(s.method), METHODS)
    if s.kind not in KINDS:
        raise UnknownNameError("scene kind", str(s.kind), KINDS)
    n = _as_int("N (number of bodies)", s.n)
    if not MIN_BODIES <= n <= max_n:
        raise InputError(f"N (number of bodies) must be in [{MIN_BODIES}, {max_n}], got {n}")
    if s.method == "brute" and n > BRUTE_MAX_BODIES:
        raise InputError(f"brute force is O(N^2): at most {BRUTE_MAX_BODIES} bodies, got N = {n}")
    speed = _as_float("SPEED", s.speed)
    if not 0.0 <= speed <= MAX_SPEED:
        raise InputError(f"SPEED must be in [0, {MAX_SPEED:g}] (length units per frame), got {speed:g}")
    density = _as_float("density", s.density)
    if not MIN_DENSITY <= density <= MAX_DENSITY:
        raise InputError(f"density must be in [{MIN_DENSITY:g}, {MAX_DENSITY:g}] bodies per unit volume, got {density:g}")
    seed = _as_int("seed", s.seed)
    if seed < 0:
        raise InputError(f"seed must be >= 0, got {seed}")
    return replace(s, n=n, speed=speed, density=density, seed=seed, paused=bool(s.paused))


Subscriber = Callable[[SedimentationSnapshot], None]


class SedimentationRunner:
    """Steps a sedimentation scene and detects its colliding pairs in a background thread.

    ``start()`` / ``stop()`` run the threads; ``step_once()`` advances one frame in the
    caller's thread (tests, and a paused scene). ``update(**changes)`` validates and applies
    settings; ``state()`` and ``latest()`` read the current figures and picture."""

    def __init__(self, settings: SedimentationSettings | None = None, *, steps_hz: float = 40.0,
                 draw_hz: float = 20.0, max_n: int = 200_000) -> None:
        if not steps_hz > 0 or not draw_hz > 0:
            raise InputError("steps_hz and draw_hz must be > 0")
        if max_n < MIN_BODIES:
            raise InputError(f"the largest N must be at least {MIN_BODIES}, got {max_n}")
        self.max_n = int(max_n)
        self.steps_hz = float(steps_hz)
        self.draw_hz = float(draw_hz)
        self._settings = validate_settings(settings or SedimentationSettings(), self.max_n)
        self._lock = threading.RLock()
        self._wake = threading.Event()  # settings changed / stop: leave a pause or a pacing wait
        self._stop = threading.Event()
        self._picture = threading.Condition()
        self._sub_lock = threading.Lock()
        self._subscribers: list[Subscriber] = []
        self._threads: list[threading.Thread] = []
        self._latest: SedimentationSnapshot | None = None
        self._picture_seq = 0
        self._next_picture_t = 0.0
        self._times: deque[float] = deque(maxlen=FPS_WINDOW)
        self._steps: deque[float] = deque(maxlen=FPS_WINDOW)
        self._warm = False
        self._pairs = np.zeros((0, 2), dtype=np.int64)
        self._scene = self._build_scene(self._settings)
        self._detector = make_detector(self._settings.method)
        self._detect()  # frame 0 has its pairs before anyone looks
        self._publish(force=True)

    # -- reading ---------------------------------------------------------------------------
    @property
    def settings(self) -> SedimentationSettings:
        return self._settings

    def fps(self) -> float:
        """Detection FPS over the last frames (0 before the first timed frame)."""
        total = sum(self._times)
        return len(self._times) / total if total > 0 else 0.0

    def steps_per_s(self) -> float:
        if self._settings.paused or len(self._steps) < 2:
            return 0.0
        span = self._steps[-1] - self._steps[0]
        return (len(self._steps) - 1) / span if span > 0 else 0.0

    def state(self) -> SedimentationState:
        with self._lock:
            s = self._settings
            return SedimentationState(
                method=s.method, n=s.n, speed=s.speed, kind=s.kind, density=s.density, seed=s.seed, paused=s.paused,
                size=self._scene.size, frame=self._scene.frame, fps=self.fps(), pairs=int(self._pairs.shape[0]),
                steps_per_s=self.steps_per_s(), methods=list(METHODS), kinds=list(KINDS), max_n=self.max_n,
            )

    def latest(self) -> SedimentationSnapshot:
        """The most recent published picture."""
        assert self._latest is not None
        return self._latest

    def subscribe(self, callback: Subscriber) -> Callable[[], None]:
        """Call ``callback(snapshot)`` for every published picture (on the runner's drawing
        thread, at most ``draw_hz`` times per second); returns a function that unsubscribes."""
        with self._sub_lock:
            self._subscribers.append(callback)

        def unsubscribe() -> None:
            with self._sub_lock:
                if callback in self._subscribers:
                    self._subscribers.remove(callback)

        return unsubscribe

    # -- changing --------------------------------------------------------------------------
    def update(self, **changes: object) -> SedimentationState:
        """Change settings (fields of :class:`SedimentationSettings`; ``None`` means keep).
        Raises ``InputError`` / ``UnknownNameError`` and changes nothing on bad input. A new
        N, kind, density or seed rebuilds the scene; a new SPEED applies to the moving scene;
        a new method starts a fresh detector on the same scene."""
        unknown = set(changes) - set(SedimentationSettings.__dataclass_fields__)
        if unknown:
            raise InputError(f"unknown sedimentation setting(s): {', '.join(sorted(unknown))}")
        given = {k: v for k, v in changes.items() if v is not None}
        with self._lock:
            old = self._settings
            new = validate_settings(replace(old, **given), self.max_n)  # type: ignore[arg-type]
            if new == old:
                return self.state()
            rebuild = (new.n, new.kind, new.density, new.seed) != (old.n, old.kind, old.density, old.seed)
            # build first (either may raise), then swap: a failed change leaves everything as it was
            scene = self._build_scene(new) if rebuild else self._scene
            detector = make_detector(new.method) if new.method != old.method else self._detector
            if rebuild and detector is self._detector:
                detector.reset()
            scene.speed = new.speed
            self._scene, self._detector, self._settings = scene, detector, new
            if rebuild or new.method != old.method:
                self._times.clear()
                self._warm = False
                self._detect()
            self._steps.clear()
            self._publish(force=True)
            log.info("sedimentation settings: %s", new)
        self._wake.set()
        return self.state()

    def toggle_pause(self) -> SedimentationState:
        with self._lock:
            return self.update(paused=not self._settings.paused)

    # -- running ---------------------------------------------------------------------------
    def start(self) -> None:
        if self._threads:
            return
        self._stop.clear()
        self._threads = [
            threading.Thread(target=self._sim_loop, name="sedimentation-sim", daemon=True),
            threading.Thread(target=self._draw_loop, name="sedimentation-draw", daemon=True),
        ]
        for t in self._threads:
            t.start()

    def stop(self) -> None:
        self._stop.set()
        self._wake.set()
        with self._picture:
            self._picture.notify_all()
        for t in self._threads:
            t.join(timeout=5.0)
        self._threads = []

    def step_once(self) -> SedimentationSnapshot:
        """Advance one frame, detect, and publish its picture (whatever the drawing rate)."""
        with self._lock:
            self._advance()
            self._publish(force=True)
            return self._latest  # type: ignore[return-value]

    # -- internals -------------------------------------------------------------------------
    @staticmethod
    def _build_scene(s: SedimentationSettings) -> Scene:
        return make_scene(s.kind, n=s.n, density=s.density, speed=s.speed, seed=s.seed)

    def _detect(self) -> None:
        """Run the detector on the current frame; time only this call."""
        t0 = time.perf_counter()
        pairs = self._detector.update(self._scene.centres, self._scene.radii)
        dt = time.perf_counter() - t0
        self._pairs = pairs
        if self._warm:
            self._times.append(dt)
        # The first call after a new detector or scene builds its structures (and may compile):
        # not the steady-state figure the thesis reports, so it stays out of the window.
        self._warm = True

    def _advance(self) -> None:
        self._scene.step()
        self._detect()
        self._steps.append(time.monotonic())

    def _publish(self, force: bool = False) -> None:
        """Make a picture of the current frame if one is due (caller holds the lock)."""
        now = time.monotonic()
        if not force and now < self._next_picture_t:
            return
        interval = max(1.0 / self.draw_hz, self._scene.n / MAX_POINTS_PER_S)
        self._next_picture_t = now + interval
        colliding = np.zeros(self._scene.n, dtype=bool)
        colliding[self._pairs.ravel()] = True
        snap = SedimentationSnapshot(
            settings=self._settings, frame=self._scene.frame, size=self._scene.size, fps=self.fps(),
            steps_per_s=self.steps_per_s(), centres=self._scene.centres.copy(), radii=self._scene.radii.copy(),
            pairs=self._pairs.copy(), colliding=colliding,
        )
        with self._picture:
            self._latest = snap
            self._picture_seq += 1
            self._picture.notify_all()

    def _sim_loop(self) -> None:
        period = 1.0 / self.steps_hz
        next_t = time.monotonic()
        while not self._stop.is_set():
            if self._settings.paused:
                self._wake.wait(timeout=PAUSED_PICTURE_S)
                self._wake.clear()
                with self._lock:
                    self._publish()  # the same frame again: keeps the views' status in step
                next_t = time.monotonic()
                continue
            try:
                with self._lock:
                    if self._settings.paused:
                        continue
                    self._advance()
                    self._publish()
            except Exception:  # noqa: BLE001 - keep the view alive; the log says what broke
                log.exception("sedimentation frame failed (%s); pausing", self._settings)
                with self._lock:
                    self._settings = replace(self._settings, paused=True)
                    self._publish(force=True)
                continue
            next_t = max(next_t + period, time.monotonic() - period)  # no burst after a stall
            # always pause a moment: the detectors may hold the GIL for a whole frame, and the
            # web server and viser need a turn between frames even when the scene runs behind
            delay = max(next_t - time.monotonic(), MIN_GAP_S)
            if self._wake.wait(timeout=delay):
                self._wake.clear()

    def _draw_loop(self) -> None:
        seen = -1
        while not self._stop.is_set():
            with self._picture:
                self._picture.wait_for(lambda: self._picture_seq != seen or self._stop.is_set(), timeout=0.5)
                if self._stop.is_set():
                    return
                if self._picture_seq == seen:
                    continue
                seen = self._picture_seq
                snap = self._latest
            with self._sub_lock:
                subscribers = list(self._subscribers)
            for callback in subscribers:
                try:
                    callback(snap)  # type: ignore[arg-type]
                except Exception:  # noqa: BLE001 - one broken view must not stop the others
                    log.exception("sedimentation subscriber %r failed", callback)
