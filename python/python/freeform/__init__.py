"""FreeForm from Python: mesh-free, reduced-order elastodynamics from skinning eigenmodes of
RKPM kernels.

Everything is SI (m, kg, s, Pa) and float64; points are ``(n, 3)`` numpy arrays. The work is
done by the Rust library (``freeform._native``); long calls release the GIL.

A basis for a bar, evaluated at its own points::

    import freeform
    points = freeform.Geometry.box([0, 0, 0], [1, 0.2, 0.2]).integration_points(2000)
    basis = freeform.build_basis(points, freeform.Material(1e6, 0.45, 1000), modes=8, kernels=200)
    w = basis.weights(points.positions)   # (n, 9): the constant handle, then 8 modes
"""

import json
import pathlib
from os import PathLike
from typing import Any, Callable, Optional, Union

import numpy as np

from . import _native
from ._native import (
    Basis,
    BasisError,
    FileFormatError,
    FrameWriter,
    FreeFormError,
    Geometry,
    IntegrationPoints,
    Material,
    SceneError,
    Splats,
    StepError,
)
from ._native import build_basis as _build_basis
from ._native import render_preview as _render_preview
from ._native import GeometryError
from ._native import simulate_scene_file as _simulate_scene_file

__all__ = [
    "Basis",
    "BasisError",
    "FileFormatError",
    "FrameWriter",
    "FreeFormError",
    "Geometry",
    "GeometryError",
    "IntegrationPoints",
    "Material",
    "Scene",
    "SceneError",
    "Simulation",
    "Splats",
    "StepError",
    "build_basis",
    "render_preview",
    "simulate_scene_file",
]

PathType = Union[str, "PathLike[str]"]


def _stage_printer(total_label: str):
    """A ``progress(label, done, total)`` for ``progress=True``: a tqdm bar when tqdm is
    installed, else a line on stderr per stage."""
    try:
        from tqdm import tqdm
    except ImportError:
        import sys

        def report(label, done, total):
            print(f"{label} ({done}/{total})", file=sys.stderr, flush=True)

        return report
    bar = None

    def report(label, done, total):
        nonlocal bar
        if bar is None:
            bar = tqdm(total=total, desc=total_label)
        bar.set_description(label)
        bar.n = done
        bar.refresh()
        if done == total:
            bar.close()

    return report


def build_basis(
    points: IntegrationPoints,
    material: Material,
    modes: int = 16,
    kernels: int = 1000,
    threads: Optional[int] = None,
    progress=None,
) -> Basis:
    """The skinning basis of ``points`` (Sec. 4-5): ``kernels`` RKPM kernels, the ``modes``
    lowest generalized eigenmodes of the elastic Hessian at rest against the mass.
    ``threads`` caps the threads (all cores by default; a fixed count is bit-identical);
    ``progress`` is a callable ``progress(label, done, total)`` told as each of the three
    stages begins and when the basis is built, or True for a tqdm bar.

    Raises ``BasisError`` for m >= K or a point no kernel reaches, ``SceneError`` for a
    material that is not one."""
    if progress is True:
        progress = _stage_printer("basis")
    return _build_basis(points, material, modes, kernels, threads, progress or None)


def render_preview(points, values=None, opacity=None, up=(0.0, 1.0, 0.0), width: int = 512,
                   height: int = 512) -> np.ndarray:
    """A ``(height, width, 3)`` uint8 RGB quick look at ``points`` (``(n, 3)``, m) or at a
    ``Splats`` table (its centres, with its opacities unless ``opacity`` is given), each point
    a round splat coloured by ``values`` (``(n,)``, e.g. von Mises stress; grey without), on
    white, seen from 30° about and 20° above ``up``."""
    if isinstance(points, Splats):
        if opacity is None and "opacity" in points.properties:
            opacity = 1.0 / (1.0 + np.exp(-points.column("opacity")))
        points = points.positions
    return _render_preview(
        points,
        None if values is None else np.asarray(values, dtype=np.float64).tolist(),
        None if opacity is None else np.asarray(opacity, dtype=np.float64).tolist(),
        [float(u) for u in up],
        int(width),
        int(height),
    )


def simulate_scene_file(
    path: PathType,
    out_dir: PathType = "freeform-out",
    cache_dir: Optional[PathType] = None,
    threads: Optional[int] = None,
    progress: Optional[Callable[[str, Optional[int], Optional[int]], Any]] = None,
) -> dict[str, Any]:
    """Run a scene file (TOML or JSON; ``docs/scene-files.md``) and write its frames and
    ``summary.json`` under ``out_dir``; return the summary as a dict (times in ms and s,
    lengths in m, energies in J). Cubatures are cached under ``cache_dir`` when given.

    ``threads`` caps the threads it uses (all cores by default). ``progress(label, done,
    total)`` is called as work advances: a stage's label with units done and its length
    (``"simulate"``: steps), or a status line with ``done`` and ``total`` None.

    Raises ``ValueError`` naming the file and field for a bad scene, and the stage for a run
    that fails.
    """
    summary = _simulate_scene_file(
        str(path),
        str(out_dir),
        None if cache_dir is None else str(cache_dir),
        threads,
        progress,
    )
    return json.loads(summary)


def _run_steps(stepped, steps: int, on_frame, progress) -> list[dict[str, Any]]:
    """``steps`` calls of ``stepped.step()``, ``on_frame(stepped, report)`` after each (``False``
    stops early), ``progress`` told as they go; the reports."""
    report_progress = _progress_reporter(progress, steps, "simulate")
    reports = []
    for done in range(1, steps + 1):
        report = stepped.step()
        reports.append(report)
        report_progress(done)
        if on_frame is not None and on_frame(stepped, report) is False:
            break
    return reports


class Simulation:
    """A reduced simulation stepped from Python.

    ``scene`` and ``simulation`` are dicts with the keys of a scene file's ``[scene]`` and
    ``[simulation]`` tables (``docs/scene-files.md``; every key optional), e.g.::

        scene = {
            "gravity": [0, -9.8, 0],                                   # m/s²
            "constraints": [{"region": {"below": {"axis": 0, "value": 0.05}}, "motion": "rest"}],
            "floor": {"normal": [0, 1, 0], "offset": -0.5, "friction": 0.3},
        }
        simulation = {"time_step": 0.01, "steps": 100, "quadrature": {"kind": "full"}}

    ``pinned`` lists sets of integration-point indices (e.g. ``np.flatnonzero(mask)``) held
    at rest by the same penalty as the scene's constraints; ``threads`` pins the threads its
    setup and steps run on (all cores by default; a fixed count gives bit-identical runs).
    ``simulation["steps"]`` is the planned length of the run, which the automatic quadrature
    weighs; ``points``, ``output_every`` and ``stress`` do not apply here. The basis given is
    held by the pin penalty with the pointwise volumetric term (``pins`` and ``pressure``
    default to ``"penalty"`` and ``"pointwise"`` here); a scene file's defaults, the weighted
    basis and the projected term, need a basis built for them: use ``simulate_scene_file``.
    """

    def __init__(
        self,
        basis: Basis,
        points: IntegrationPoints,
        material: Material,
        scene: Optional[dict[str, Any]] = None,
        simulation: Optional[dict[str, Any]] = None,
        cache_dir: Optional[PathType] = None,
        pinned: Optional[list[np.ndarray]] = None,
        threads: Optional[int] = None,
    ) -> None:
        self._native = _native.Simulation(
            basis,
            points,
            material,
            json.dumps(scene or {}, allow_nan=False),
            json.dumps(simulation or {}, allow_nan=False),
            None if cache_dir is None else str(cache_dir),
            [np.asarray(p, dtype=np.int64).ravel().tolist() for p in (pinned or [])],
            threads,
        )

    def step(self) -> dict[str, Any]:
        """Advance one backward-Euler step; return Newton's report (``converged``,
        ``iterations``, ``hessian_assemblies``, ``line_search_cuts``, ``residual``)."""
        return json.loads(self._native.step())

    def run(self, steps: int, on_frame=None, progress=None) -> list[dict[str, Any]]:
        """``steps`` steps; ``on_frame(simulation, report)`` after each (return ``False`` to
        stop early); ``progress``: a callable ``progress(label, done, total)`` or True for a
        tqdm bar (at most ten updates a second). Ctrl-C stops after the step in progress.
        Returns the steps' reports."""
        return _run_steps(self, steps, on_frame, progress)

    @property
    def time(self) -> float:
        """Simulated time (s)."""
        return self._native.time

    @property
    def coordinates(self) -> np.ndarray:
        """Reduced coordinates z, ``(12 (m + 1),)``: handle j's 3 × 4 transform minus the
        identity, ``Z_j[r, c] = z[4 (m + 1) r + 4 j + c]`` (handle 0 the constant one)."""
        return self._native.coordinates

    @property
    def velocity(self) -> np.ndarray:
        """Velocity of the reduced coordinates, ``(12 (m + 1),)``."""
        return self._native.velocity

    def set_state(self, coordinates: np.ndarray, velocity: np.ndarray, time: float) -> None:
        """Replace the state: coordinates z, their velocity and the time (s)."""
        self._native.set_state(
            np.asarray(coordinates, dtype=np.float64).tolist(),
            np.asarray(velocity, dtype=np.float64).tolist(),
            float(time),
        )

    @property
    def mechanical_energy(self) -> float:
        """Kinetic, elastic, gravitational and penalty energy (J)."""
        return self._native.mechanical_energy

    @property
    def quadrature(self) -> dict[str, Any]:
        """The elastic quadrature used (``kind``, ``points``, ``cubature``, ``choice``)."""
        return json.loads(self._native.quadrature)

    def deformed_points(
        self, points: Optional[np.ndarray] = None, out: Optional[np.ndarray] = None
    ) -> np.ndarray:
        """Deformed positions ``(n, 3)`` (m) of rest ``points`` ``(n, 3)`` (m; the integration
        points when omitted). With ``out`` (a C-contiguous ``(n, 3)`` float64 array) the
        positions are written there and ``out`` is returned: nothing is allocated in numpy."""
        return self._native.deformed_points(points, out)

    def deformation_gradients(self, points: Optional[np.ndarray] = None) -> np.ndarray:
        """Deformation gradients F ``(n, 3, 3)``, ``F[i, r, c] = ∂x_r/∂X_c`` at point i, at rest
        ``points`` ``(n, 3)`` (m; the integration points when omitted)."""
        return self._native.deformation_gradients(points)

    def stress(self, points: Optional[np.ndarray] = None) -> dict[str, Any]:
        """The stress at rest ``points`` (the integration points when omitted): ``cauchy``
        ``(n, 3, 3)``, ``principal`` ``(n, 3)`` (σ₁ ≥ σ₂ ≥ σ₃) and ``von_mises`` ``(n,)`` in Pa,
        and ``inverted``, the indices of points with det F ≤ 0 (their stress is 0)."""
        cauchy, principal, von_mises, inverted = self._native.stress(points)
        return {
            "cauchy": cauchy,
            "principal": principal,
            "von_mises": von_mises,
            "inverted": inverted,
        }

    def deformed_splats(self, splats: Splats) -> tuple[Splats, int]:
        """``splats`` (rest centres in m) deformed by the current state: centres moved,
        covariances mapped to ``F Σ Fᵀ``, higher spherical harmonics rotated; and the number
        of splats with det F ≤ 0. Write the result with ``Splats.write``."""
        return self._native.deformed_splats(splats)


def _progress_reporter(progress, total: int, label: str):
    """A function ``report(done)`` that shows progress at most ten times a second: through
    ``progress(label, done, total)`` when it is callable, a tqdm bar when ``progress`` is True
    and tqdm is installed (a line on stderr otherwise), nothing when it is None or False."""
    import time

    if not progress:
        return lambda done: None
    if callable(progress):
        last = [0.0]

        def report(done):
            now = time.monotonic()
            if done == total or now - last[0] >= 0.1:
                last[0] = now
                progress(label, done, total)

        return report
    try:
        from tqdm import tqdm

        bar = tqdm(total=total, desc=label)

        def report(done):
            bar.n = done
            bar.refresh() if done == total else bar.update(0)
            if done == total:
                bar.close()

        return report
    except ImportError:
        import sys

        last = [0.0]

        def report(done):
            now = time.monotonic()
            if done == total or now - last[0] >= 0.1:
                last[0] = now
                end = "\n" if done == total else ""
                print(f"\r{label}: {done}/{total}", end=end, file=sys.stderr, flush=True)

        return report


class Scene:
    """Several objects stepped together by backward Euler, touching one another, the floor and
    the colliders: what a scene file with ``[[objects]]`` runs (``docs/scene-files.md``).

    ``gravity`` (m/s², a vector), ``floor`` and ``colliders`` take the keys of the scene file's
    ``[scene]``; ``contact`` those of its ``[contact]`` (default ``{"radius": 0.02}``: samples
    of different objects closer than 2 cm repel); ``simulation`` those of ``[simulation]``
    (``time_step``, ``quadrature`` — e.g. ``{"kind": "full"}`` — and ``hessian_reuse`` override
    its keys); ``threads`` pins the threads its setup and steps
    run on (all cores by default; a fixed count gives bit-identical runs). Objects, pins, the
    floor, colliders and contact are set before the first step::

        scene = freeform.Scene(time_step=0.01)
        scene.set_gravity([0, -9.8, 0])
        scene.set_floor(offset=0.0, friction=0.3)
        a = scene.add_object(basis, points, rubber, geometry=box, position=[0, 0.3, 0])
        scene.pin(a, {"below": {"axis": 0, "value": 0.05}})
        scene.run(100)
        x = scene.deformed_points(a, box.display_points())
    """

    def __init__(
        self,
        time_step: Optional[float] = None,
        gravity=None,
        floor: Optional[dict[str, Any]] = None,
        colliders: Optional[list[dict[str, Any]]] = None,
        contact: Optional[dict[str, Any]] = None,
        simulation: Optional[dict[str, Any]] = None,
        cache_dir: Optional[PathType] = None,
        threads: Optional[int] = None,
        quadrature: Optional[dict[str, Any]] = None,
        hessian_reuse: Optional[bool] = None,
    ) -> None:
        self._threads = threads
        self._native_scene = None
        self._stepped = False
        self._writers: dict[str, list] = {}
        self._simulation = dict(simulation or {})
        if time_step is not None:
            self._simulation["time_step"] = float(time_step)
        if quadrature is not None:
            self._simulation["quadrature"] = quadrature
        if hessian_reuse is not None:
            self._simulation["hessian_reuse"] = bool(hessian_reuse)
        self._scene: dict[str, Any] = {"colliders": list(colliders or [])}
        if gravity is not None:
            self.set_gravity(gravity)
        if floor is not None:
            self._scene["floor"] = dict(floor)
        self._contact = dict(contact or {"radius": 0.02})
        self._cache_dir = None if cache_dir is None else str(cache_dir)
        self._objects: list[dict[str, Any]] = []

    # What acts on the objects, set before the first step.
    def _unstarted(self, what: str) -> None:
        if self._stepped:
            raise SceneError(f"{what} is set before the first step; this scene has started")
        # A native scene built for a look before stepping is built again with the change.
        self._native_scene = None

    def set_gravity(self, acceleration) -> None:
        """Gravitational acceleration (m/s², a vector, e.g. ``[0, -9.8, 0]``)."""
        self._unstarted("gravity")
        self._scene["gravity"] = np.asarray(acceleration, dtype=np.float64).reshape(3).tolist()

    def set_floor(self, normal=(0.0, 1.0, 0.0), offset: float = 0.0, friction: float = 0.0) -> None:
        """The half-space ``normal · x >= offset`` (m) the objects stay above, with Coulomb
        friction ``friction``."""
        self._unstarted("the floor")
        self._scene["floor"] = {
            "normal": np.asarray(normal, dtype=np.float64).reshape(3).tolist(),
            "offset": float(offset),
            "friction": float(friction),
        }

    def add_collider(self, shape: dict[str, Any], path=None, friction: float = 0.0,
                     parent: Optional[int] = None) -> int:
        """A kinematic collider (the scene file's ``[[scene.colliders]]``): ``shape`` e.g.
        ``{"sphere": {"radius": 0.1}}``, ``path`` its keyframes (``[{"time": 0,
        "translation": [x, y, z]}, ...]``; at rest at the origin when None), ``friction``, and
        the collider it rides on (``parent``). Returns its index."""
        self._unstarted("a collider")
        collider: dict[str, Any] = {
            "shape": shape,
            "path": path if path is not None else [{"time": 0.0, "translation": [0.0, 0.0, 0.0]}],
            "friction": float(friction),
        }
        if parent is not None:
            collider["parent"] = int(parent)
        self._scene["colliders"].append(collider)
        return len(self._scene["colliders"]) - 1

    def set_contact(self, radius: float, friction: float = 0.0, model: Optional[Any] = None,
                    stiffness_factor: Optional[float] = None) -> None:
        """Contact between the objects (the scene file's ``[contact]``): samples of different
        objects closer than ``radius`` (m) repel, with Coulomb ``friction``."""
        self._unstarted("contact")
        contact: dict[str, Any] = {"radius": float(radius), "friction": float(friction)}
        if model is not None:
            contact["model"] = model
        if stiffness_factor is not None:
            contact["stiffness_factor"] = float(stiffness_factor)
        self._contact = contact

    def add_object(
        self,
        basis: Basis,
        points: IntegrationPoints,
        material: Material,
        geometry: Optional[Geometry] = None,
        position=None,
        rotation=None,
        velocity=None,
        constraints: Optional[list[dict[str, Any]]] = None,
        pinned: Optional[list[np.ndarray]] = None,
        name: Optional[str] = None,
    ) -> int:
        """Adds an object and returns its index ``k``; ``name`` (default ``object<k>``) names
        its folder in ``write_frame``. ``position`` (m) and ``rotation`` (a
        quaternion ``[i, j, k, w]``) place its rest frame, ``x = R X + position``; ``velocity``
        (m/s) starts it moving. ``constraints`` are its held and moving regions in its rest
        frame (the scene file's ``[[objects.constraints]]``); ``pinned`` sets of its
        integration-point indices held at rest. ``geometry``'s surface samples touch the other
        objects (its integration points do when omitted)."""
        self._unstarted("an object")
        placement: dict[str, Any] = {}
        for key, value in (("position", position), ("rotation", rotation), ("velocity", velocity)):
            if value is not None:
                placement[key] = np.asarray(value, dtype=np.float64).tolist()
        self._objects.append(
            {
                "basis": basis,
                "points": points,
                "material": material,
                "geometry": geometry,
                "placement": placement,
                "constraints": list(constraints or []),
                "pinned": [np.asarray(p, dtype=np.int64).ravel().tolist() for p in (pinned or [])],
                "name": name if name is not None else f"object{len(self._objects)}",
            }
        )
        return len(self._objects) - 1

    def write_frame(self, out_dir: PathType, index: int) -> list[tuple[str, str]]:
        """Writes frame ``index`` of every object as PLY and VTK (``<out_dir>/<name>/
        frame_NNNNN.ply`` / ``.vtk``, as ``simulate_scene_file`` does): its geometry's surface
        or cloud, or its integration points without one. Returns the files written."""
        key = str(out_dir)
        if key not in self._writers:
            self._writers[key] = [
                FrameWriter(
                    pathlib.Path(out_dir) / o["name"],
                    o["geometry"] if o["geometry"] is not None
                    else Geometry.from_points(o["points"].positions),
                )
                for o in self._objects
            ]
        return [
            writer.write(index, self.deformed_points(k, writer.rest_positions), self.time)
            for k, writer in enumerate(self._writers[key])
        ]

    def pin(self, k: int, where, motion: Any = "rest") -> None:
        """Holds part of object ``k``: ``where`` a region of its rest frame (the scene file's
        ``region``, e.g. ``{"below": {"axis": 0, "value": 0.05}}``) moving by ``motion``
        (``"rest"`` or the scene file's motions), or a boolean mask over its integration points
        held at rest."""
        self._unstarted("a pin")
        if not 0 <= k < len(self._objects):
            raise ValueError(f"no object {k}: the scene has {len(self._objects)}")
        if isinstance(where, dict):
            self._objects[k]["constraints"].append({"region": where, "motion": motion})
            return
        mask = np.asarray(where, dtype=bool).ravel()
        if mask.shape[0] != len(self._objects[k]["points"]):
            raise ValueError(
                f"a mask of {mask.shape[0]} values for {len(self._objects[k]['points'])} points"
            )
        if motion != "rest":
            raise ValueError("a mask holds its points at rest; give a region to move them")
        self._objects[k]["pinned"].append(np.flatnonzero(mask).tolist())

    @property
    def _native(self):
        """The native scene, built with every object at the first use after setting up."""
        if self._native_scene is None:
            scene = dict(self._scene)
            native = _native.Scene(
                json.dumps(scene, allow_nan=False),
                json.dumps(self._simulation, allow_nan=False),
                json.dumps(self._contact, allow_nan=False),
                self._cache_dir,
                self._threads,
            )
            for o in self._objects:
                native.add_object(
                    o["basis"],
                    o["points"],
                    o["material"],
                    json.dumps(o["placement"], allow_nan=False),
                    json.dumps(o["constraints"], allow_nan=False),
                    o["pinned"],
                    o["geometry"],
                )
            self._native_scene = native
        return self._native_scene

    def __len__(self) -> int:
        return len(self._objects)

    def step(self) -> dict[str, Any]:
        """Advance every object one step (the first step builds the simulator); return the
        Newton reports: ``converged``, ``objects`` (one report each), ``joint_groups``,
        ``active_pairs``. Raises ``StepError`` (with ``.step``) for a step that fails."""
        report = json.loads(self._native.step())
        self._stepped = True
        return report

    def run(self, steps: int, on_frame=None, progress=None) -> list[dict[str, Any]]:
        """``steps`` steps; ``on_frame(scene, report)`` after each (return ``False`` to stop
        early); ``progress``: a callable ``progress(label, done, total)`` or True for a tqdm bar
        (at most ten updates a second). Ctrl-C stops after the step in progress."""
        return _run_steps(self, steps, on_frame, progress)

    @property
    def time(self) -> float:
        """Simulated time (s)."""
        return self._native.time

    @property
    def mechanical_energy(self) -> float:
        """Every object's kinetic, elastic, gravitational, penalty and contact energy (J)."""
        return self._native.mechanical_energy

    def coordinates(self, k: int) -> np.ndarray:
        """Object ``k``'s reduced coordinates z, ``(12 (m + 1),)``."""
        return self._native.coordinates(k)

    def deformed_points(self, k: int, points=None, out: Optional[np.ndarray] = None) -> np.ndarray:
        """World positions ``(n, 3)`` (m) of object ``k``'s rest ``points`` (its integration
        points when omitted); written into ``out`` and ``out`` returned when given."""
        return self._native.deformed_points(k, points, out)

    def deformation_gradients(self, k: int, points=None) -> np.ndarray:
        """Object ``k``'s deformation gradients F ``(n, 3, 3)`` at its rest ``points``."""
        return self._native.deformation_gradients(k, points)

    def stress(self, k: int, points=None) -> dict[str, Any]:
        """Object ``k``'s stress at its rest ``points`` (its integration points when omitted):
        ``cauchy`` ``(n, 3, 3)``, ``principal`` ``(n, 3)``, ``von_mises`` ``(n,)`` (Pa), and
        ``inverted``, the indices of points with det F <= 0 (their stress is 0)."""
        cauchy, principal, von_mises, inverted = self._native.stress(k, points)
        return {"cauchy": cauchy, "principal": principal, "von_mises": von_mises, "inverted": inverted}

    def deformed_splats(self, k: int, splats: Splats) -> tuple[Splats, int]:
        """``splats`` (rest centres in object ``k``'s rest frame, m) deformed with object
        ``k``: centres moved, covariances ``F Σ Fᵀ``, higher SH rotated; and the number of
        splats with det F <= 0."""
        return self._native.deformed_splats(k, splats)

    def point_transforms(self, k: int, points=None) -> np.ndarray:
        """Object ``k``'s per-point transforms ``(n, 4, 4)``, ``[[F, t], [0, 1]]`` with
        ``x = F X + t`` at each rest point (Kaolin's point transforms, homogeneous)."""
        return self._native.point_transforms(k, points)
