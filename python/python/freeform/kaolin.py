"""Kaolin's Simplicits "easy API" on FreeForm: the names and call order of
``kaolin.physics.simplicits`` (``SimplicitsObject``, ``SimplicitsScene``), with FreeForm's
RKPM eigenmode basis in place of the trained network and FreeForm's simulator underneath.

Kaolin's conventions hold at this boundary:

- ``set_scene_gravity(acc_gravity)`` takes Kaolin's sign: the potential is ``ρ g · x``, so the
  default ``(0, 9.8, 0)`` pulls towards −y.
- ``num_handles`` counts the handles besides the constant (rigid) one, as Kaolin's does; it is
  FreeForm's number of modes m.
- Boundary conditions are a function of the object's points returning a boolean mask, and the
  floor is ``floor_height`` along ``floor_axis`` (above it, or below it with ``flip_floor``).
- ``init_tfm`` is the 3 × 4 offset added to the rigid handle's transform.

What differs: arrays are numpy float64 (CPU torch tensors are accepted and converted, CUDA
tensors refused with a clear error), there is no
device, and the penalties are FreeForm's, which scale with the material
(``docs/scene-files.md``), so ``floor_penalty`` and ``bdry_penalty`` are accepted, not used, and
warned about once.
``num_cub_pts`` draws that many points at random for the elastic energy, as Kaolin does; leave
it ``None`` for FreeForm's own quadrature. Objects do not touch each other (as in Kaolin's easy
API); each is stepped on its own.
"""

import warnings
from typing import Any, Callable, Optional

import numpy as np

from . import Basis, IntegrationPoints, Material, Simulation, build_basis

__all__ = ["SimplicitsObject", "SimplicitsScene"]


def _array(values, shape=None) -> np.ndarray:
    """``values`` (numpy, a CPU torch tensor or a sequence) as a float64 numpy array; a tensor
    on another device is refused (moving it is the caller's choice)."""
    if hasattr(values, "detach"):
        device = getattr(values, "device", None)
        kind = getattr(device, "type", "cpu")
        if kind != "cpu":
            raise ValueError(
                f"a torch tensor on {device} was given: FreeForm runs on the CPU, so pass "
                "tensor.cpu() (or a numpy array)"
            )
        values = values.detach().numpy()
    array = np.asarray(values, dtype=np.float64)
    return array if shape is None else array.reshape(shape)


_WARNED: set[str] = set()


def _warn_once(key: str, message: str) -> None:
    """A ``UserWarning`` with ``message`` the first time ``key`` comes up in this process."""
    if key not in _WARNED:
        _WARNED.add(key)
        warnings.warn(message, UserWarning, stacklevel=3)


def _material(pts: np.ndarray, yms, prs, rhos) -> Material:
    """Kaolin's per-point (or scalar) ``yms``, ``prs`` and ``rhos`` as a material: one value
    everywhere when each is uniform, else the values at the points."""
    values = []
    for name, given in (("yms", yms), ("prs", prs), ("rhos", rhos)):
        array = _array(given).ravel()
        if array.size not in (1, len(pts)):
            raise ValueError(f"{name}: {array.size} values for {len(pts)} points (give one or {len(pts)})")
        values.append(array)
    if all(np.all(v == v[0]) for v in values):
        return Material(*(float(v[0]) for v in values))
    return Material.at_points(pts, *(v.tolist() for v in values))


class SimplicitsObject:
    """An object: its points, material and skinning basis."""

    def __init__(self, pts, yms, prs, rhos, appx_vol, num_handles: int = 16, num_kernels: int = 1000):
        self.pts = _array(pts)
        if self.pts.ndim != 2 or self.pts.shape[1] != 3:
            raise ValueError(f"pts must have shape (n, 3), got {self.pts.shape}")
        n = self.pts.shape[0]
        self.appx_vol = float(_array(appx_vol))
        self.num_handles = int(num_handles)
        self.material = _material(self.pts, yms, prs, rhos)
        # Every point carries an equal share of the volume, as Kaolin's integration sampling.
        self.points = IntegrationPoints(self.pts, [self.appx_vol / n] * n)
        self.basis: Basis = build_basis(
            self.points, self.material, modes=self.num_handles, kernels=num_kernels
        )

    @classmethod
    def create_with_rkpm(
        cls, pts, yms, prs, rhos, appx_vol, num_handles: int = 16, num_kernels: int = 1000
    ) -> "SimplicitsObject":
        """An object whose handles are FreeForm's skinning eigenmodes of ``num_kernels`` RKPM
        kernels (no training): ``pts`` ``(n, 3)`` in m, ``yms`` in Pa, ``prs``, ``rhos`` in
        kg/m³ (one value, or per-point arrays), ``appx_vol`` the object's volume
        in m³."""
        return cls(pts, yms, prs, rhos, appx_vol, num_handles, num_kernels)

    def weights(self, points=None) -> np.ndarray:
        """Skinning weights ``(n, num_handles + 1)`` at ``points`` (the object's by default),
        the constant handle last, as Kaolin orders them."""
        x = self.pts if points is None else _array(points)
        w = self.basis.weights(x)
        return np.concatenate([w[:, 1:], w[:, :1]], axis=1)


class _SceneObject:
    """One object of a scene: what the scene sets on it, and its simulation once built."""

    def __init__(self, obj: SimplicitsObject, num_cub_pts: Optional[int], init_tfm):
        self.obj = obj
        self.num_cub_pts = num_cub_pts
        self.init_tfm = None if init_tfm is None else _array(init_tfm, (3, 4))
        self.boundaries: dict[str, np.ndarray] = {}
        self.simulation: Optional[Simulation] = None
        # The state to carry into the next simulation built (after a change of forces).
        self.state: Optional[tuple] = None


class SimplicitsScene:
    """A scene of objects stepped together by backward Euler."""

    def __init__(self, device=None, dtype=None, timestep: float = 0.03, max_newton_steps: int = 20,
                 max_ls_steps: int = 30):
        self.timestep = float(timestep)
        self.current_sim_step = 0
        self._gravity: Optional[np.ndarray] = None
        self._floor: Optional[dict[str, Any]] = None
        self._objects: dict[int, _SceneObject] = {}
        self._next_id = 0

    # Objects.
    def add_object(self, sim_object: SimplicitsObject, num_cub_pts: Optional[int] = None,
                   init_tfm=None) -> int:
        """Adds an object; returns its id."""
        self._objects[self._next_id] = _SceneObject(sim_object, num_cub_pts, init_tfm)
        self._next_id += 1
        return self._next_id - 1

    def remove_object(self, obj_idx: int) -> None:
        self._objects.pop(obj_idx, None)

    def get_object(self, obj_idx: int) -> SimplicitsObject:
        return self._objects[obj_idx].obj

    # Forces and boundary conditions: each change rebuilds the objects' simulations at their
    # current state.
    def set_scene_gravity(self, acc_gravity=(0.0, 9.8, 0.0)) -> None:
        """Gravity with Kaolin's sign: potential ``ρ g · x`` (the default pulls towards −y)."""
        self._gravity = _array(acc_gravity, (3,))
        self._changed()

    def set_scene_floor(self, floor_height: float = 0.0, floor_axis: int = 1,
                        floor_penalty: Optional[float] = None, flip_floor: bool = False) -> None:
        """A floor at ``floor_height`` along ``floor_axis``: points stay above it (below it
        with ``flip_floor``). ``floor_penalty`` is not used (FreeForm's floor stiffness scales
        with the material); giving one warns once."""
        if floor_penalty is not None:
            _warn_once(
                "floor_penalty",
                "floor_penalty is not used: FreeForm's floor stiffness scales with the material "
                "(kappa = 1e4 (lambda + 2 mu) / L^2), calibrated against the FEM",
            )
        if floor_axis not in (0, 1, 2):
            raise ValueError(f"floor_axis must be 0, 1 or 2, got {floor_axis}")
        normal = [0.0, 0.0, 0.0]
        normal[floor_axis] = -1.0 if flip_floor else 1.0
        offset = -float(floor_height) if flip_floor else float(floor_height)
        self._floor = {"normal": normal, "offset": offset}
        self._changed()

    def set_object_boundary_condition(self, obj_idx: int, name: str,
                                      fcn: Callable[[np.ndarray], Any],
                                      bdry_penalty: Optional[float] = None) -> None:
        """Holds at rest the object's points where ``fcn(points)`` is true (a boolean ``(n,)``
        mask of its ``(n, 3)`` points). ``bdry_penalty`` is not used (FreeForm's pin penalty
        scales with the material); giving one warns once."""
        if bdry_penalty is not None:
            _warn_once(
                "bdry_penalty",
                "bdry_penalty is not used: FreeForm's pin penalty scales with the material "
                "(kappa = 3e3 max E / L^2), chosen against the FEM",
            )
        o = self._objects[obj_idx]
        mask = _array(fcn(o.obj.pts)).astype(bool).ravel()
        if mask.shape != (o.obj.pts.shape[0],):
            raise ValueError(f"the boundary function must return one boolean per point, got {mask.shape}")
        if not mask.any():
            raise ValueError(f"boundary condition {name!r} selects none of the object's points")
        o.boundaries[name] = np.flatnonzero(mask)
        self._changed(obj_idx)

    def remove_object_force(self, obj_idx: int, name: str) -> None:
        """Removes a boundary condition of one object by name (or gravity / the floor, which
        are the scene's)."""
        if self._objects[obj_idx].boundaries.pop(name, None) is not None:
            self._changed(obj_idx)
        else:
            self.remove_scene_force(name)

    def remove_scene_force(self, name: str) -> None:
        """Removes ``"gravity"`` or ``"floor"``, or a boundary condition of every object."""
        if name == "gravity":
            self._gravity = None
        elif name == "floor":
            self._floor = None
        else:
            for o in self._objects.values():
                o.boundaries.pop(name, None)
        self._changed()

    # Stepping.
    def run_sim_step(self) -> None:
        """One step of ``timestep`` for every object."""
        for idx in self._objects:
            self._simulation(idx).step()
        self.current_sim_step += 1

    def reset_object(self, obj_idx: int, init_tfm=None) -> None:
        """Back to rest (with ``init_tfm``, a 3 × 4 offset of the rigid handle)."""
        o = self._objects[obj_idx]
        o.init_tfm = None if init_tfm is None else _array(init_tfm, (3, 4))
        o.simulation = None
        o.state = None

    def reset(self) -> None:
        """Every object back to rest, without initial transforms."""
        for idx in self._objects:
            self.reset_object(idx)
        self.current_sim_step = 0

    reset_scene = reset

    # Results.
    def get_object_deformed_pts(self, obj_idx: int, points=None) -> np.ndarray:
        """Deformed positions ``(n, 3)`` of the object's points (or of rest ``points``)."""
        o = self._objects[obj_idx]
        x = o.obj.pts if points is None else _array(points)
        return self._simulation(obj_idx).deformed_points(x)

    def get_object_deformation_gradient(self, obj_idx: int, points=None) -> np.ndarray:
        """Deformation gradients ``(n, 3, 3)`` at the object's points (or at rest ``points``)."""
        o = self._objects[obj_idx]
        x = o.obj.pts if points is None else _array(points)
        return self._simulation(obj_idx).deformation_gradients(x)

    def get_object_point_transforms(self, obj_idx: int, points=None) -> np.ndarray:
        """Per-point blended transforms ``(n, 3, 4)``, ``T(X) = [I | 0] + Σ_j w_j(X) Z_j``, which
        map each rest point to its deformed position: ``x = T(X) [X; 1]``."""
        o = self._objects[obj_idx]
        x = o.obj.pts if points is None else _array(points)
        w = o.obj.basis.weights(x)
        handles = w.shape[1]
        z = self._simulation(obj_idx).coordinates.reshape(3, handles, 4)
        return np.einsum("nj,rjc->nrc", w, z) + np.eye(3, 4)

    # Internals.
    def _changed(self, obj_idx: Optional[int] = None) -> None:
        """Marks objects' simulations for a rebuild (at their current state)."""
        for idx, o in self._objects.items():
            if obj_idx is None or idx == obj_idx:
                if o.simulation is not None:
                    o.state = (o.simulation.coordinates, o.simulation.velocity, o.simulation.time)
                o.simulation = None

    def _simulation(self, obj_idx: int) -> Simulation:
        o = self._objects[obj_idx]
        if o.simulation is None:
            scene: dict[str, Any] = {}
            if self._gravity is not None:
                scene["gravity"] = (-self._gravity).tolist()
            if self._floor is not None:
                scene["floor"] = self._floor
            settings: dict[str, Any] = {"time_step": self.timestep}
            if o.num_cub_pts is not None and o.num_cub_pts < len(o.obj.points):
                settings["quadrature"] = {"kind": "random_subset", "points": int(o.num_cub_pts), "seed": 0}
            o.simulation = Simulation(
                o.obj.basis, o.obj.points, o.obj.material, scene=scene, simulation=settings,
                pinned=list(o.boundaries.values()),
            )
            if o.state is not None:
                o.simulation.set_state(*o.state)
                o.state = None
            elif o.init_tfm is not None:
                z = np.zeros_like(o.simulation.coordinates)
                handles = z.size // 12
                z.reshape(3, handles, 4)[:, 0, :] = o.init_tfm
                o.simulation.set_state(z, np.zeros_like(z), 0.0)
        return o.simulation
