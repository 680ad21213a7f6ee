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
    build_basis,
    render_preview,
)
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
    "SceneError",
    "Simulation",
    "Splats",
    "StepError",
    "build_basis",
    "render_preview",
    "simulate_scene_file",
]

PathType = Union[str, "PathLike[str]"]


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
    at rest by the same penalty as the scene's constraints. ``simulation["steps"]`` is the
    planned length of the run, which the automatic quadrature
    weighs; ``points``, ``output_every`` and ``stress`` do not apply here. Held pins and a
    pressure space need a basis built for them: use ``simulate_scene_file`` for those.
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
    ) -> None:
        self._native = _native.Simulation(
            basis,
            points,
            material,
            json.dumps(scene or {}, allow_nan=False),
            json.dumps(simulation or {}, allow_nan=False),
            None if cache_dir is None else str(cache_dir),
            [np.asarray(p, dtype=np.int64).ravel().tolist() for p in (pinned or [])],
        )

    def step(self) -> dict[str, Any]:
        """Advance one backward-Euler step; return Newton's report (``converged``,
        ``iterations``, ``hessian_assemblies``, ``line_search_cuts``, ``residual``)."""
        return json.loads(self._native.step())

    def run(self, steps: int, on_frame=None) -> list[dict[str, Any]]:
        """``steps`` steps; ``on_frame(simulation, report)`` after each (return ``False`` to
        stop early). Returns the steps' reports."""
        reports = []
        for _ in range(steps):
            report = self.step()
            reports.append(report)
            if on_frame is not None and on_frame(self, report) is False:
                break
        return reports

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
