"""The Kaolin-shaped front: Kaolin's conventions (gravity sign, rigid handle last, boundary
masks, floor axis) map onto FreeForm's simulation exactly."""

import numpy as np
import pytest

import freeform
from freeform.kaolin import SimplicitsObject, SimplicitsScene

E, NU, RHO = 1e6, 0.45, 1000.0


@pytest.fixture(scope="module")
def bar():
    points = freeform.Geometry.box([0, 0, 0], [1.0, 0.25, 0.25]).integration_points(1500)
    pts = points.positions
    obj = SimplicitsObject.create_with_rkpm(
        pts, E, NU, np.full(len(pts), RHO), 1.0 * 0.25 * 0.25, num_handles=6, num_kernels=120
    )
    return obj


def test_kaolins_gravity_sign_pulls_down_and_falls_as_backward_euler(bar):
    scene = SimplicitsScene(timestep=0.01)
    idx = scene.add_object(bar)
    scene.set_scene_gravity(acc_gravity=[0, 9.8, 0])
    for _ in range(10):
        scene.run_sim_step()
    drop = 9.8 * 0.01**2 * 10 * 11 / 2
    np.testing.assert_allclose(scene.get_object_deformed_pts(idx), bar.pts - [0, drop, 0], atol=1e-8)
    assert scene.current_sim_step == 10


def test_a_boundary_mask_and_a_floor_run_exactly_as_the_same_simulation(bar):
    # The same fixed quadrature on both sides: the automatic one trains a cubature or not by
    # the time its first steps took, so two automatic runs may choose differently.
    scene = SimplicitsScene(timestep=0.01)
    idx = scene.add_object(bar, num_cub_pts=1000)
    scene.set_scene_gravity()
    scene.set_scene_floor(floor_height=-0.05, floor_axis=1)
    scene.set_object_boundary_condition(idx, "clamp", lambda x: x[:, 0] <= 0.05)
    for _ in range(8):
        scene.run_sim_step()
    sim = freeform.Simulation(
        bar.basis,
        bar.points,
        bar.material,
        scene={"gravity": [0, -9.8, 0], "floor": {"normal": [0, 1, 0], "offset": -0.05}},
        simulation={
            "time_step": 0.01,
            "quadrature": {"kind": "random_subset", "points": 1000, "seed": 0},
        },
        pinned=[np.flatnonzero(bar.pts[:, 0] <= 0.05)],
    )
    sim.run(8)
    np.testing.assert_array_equal(scene.get_object_deformed_pts(idx), sim.deformed_points())
    # The blended per-point transforms map every rest point to its deformed position.
    t = scene.get_object_point_transforms(idx)
    x = np.einsum("nrc,nc->nr", t[:, :, :3], bar.pts) + t[:, :, 3]
    np.testing.assert_allclose(x, sim.deformed_points(), atol=1e-10)
    f = scene.get_object_deformation_gradient(idx)
    np.testing.assert_array_equal(f, sim.deformation_gradients())


def test_a_change_of_forces_keeps_the_state_and_reset_returns_to_rest(bar):
    scene = SimplicitsScene(timestep=0.01)
    idx = scene.add_object(bar)
    scene.set_scene_gravity()
    for _ in range(3):
        scene.run_sim_step()
    before = scene.get_object_deformed_pts(idx)
    scene.remove_scene_force("gravity")
    np.testing.assert_array_equal(scene.get_object_deformed_pts(idx), before)
    scene.reset()
    np.testing.assert_array_equal(scene.get_object_deformed_pts(idx), bar.pts)


def test_the_rigid_handle_is_last_and_an_initial_transform_offsets_it(bar):
    w = bar.weights()
    assert w.shape == (len(bar.pts), bar.num_handles + 1)
    np.testing.assert_allclose(w[:, -1], 1.0, atol=1e-12)
    scene = SimplicitsScene()
    tfm = np.zeros((3, 4))
    tfm[:, 3] = [0.1, 0.2, -0.3]
    idx = scene.add_object(bar, init_tfm=tfm)
    np.testing.assert_allclose(scene.get_object_deformed_pts(idx), bar.pts + tfm[:, 3], atol=1e-12)


def test_per_point_moduli_are_read_at_the_points_and_bad_input_is_a_named_error(bar):
    pts = bar.pts
    graded = np.linspace(1e5, 1e6, len(pts))
    obj = SimplicitsObject.create_with_rkpm(pts, graded, NU, RHO, 0.0625, num_handles=4, num_kernels=60)
    assert obj.material.per_point
    np.testing.assert_array_equal(obj.material.youngs_modulus, graded)
    with pytest.raises(ValueError, match="yms: 2 values"):
        SimplicitsObject.create_with_rkpm(pts, [1e5, 1e6], NU, RHO, 0.0625)
    scene = SimplicitsScene()
    idx = scene.add_object(bar)
    with pytest.raises(ValueError, match="selects none"):
        scene.set_object_boundary_condition(idx, "none", lambda x: x[:, 0] < -1.0)
    with pytest.raises(ValueError, match="floor_axis"):
        scene.set_scene_floor(floor_axis=3)


def test_a_kaolin_script_drops_a_ball_onto_the_floor_where_it_comes_to_rest():
    # Kaolin's easy-API script, with only its import changed (Kaolin: `from
    # kaolin.physics.simplicits import SimplicitsObject, SimplicitsScene`): a 3000-point ball
    # cloud of radius 0.5 m dropped from 0.1 m above the floor, 17 handles (16 and the constant),
    # Kaolin's gravity sign and default time step (0.03 s).
    rng = np.random.default_rng(0)
    directions = rng.normal(size=(3000, 3))
    directions /= np.linalg.norm(directions, axis=1)[:, None]
    radii = 0.5 * rng.uniform(size=(3000, 1)) ** (1 / 3)
    pts = directions * radii + [0, 0.6, 0]
    obj = SimplicitsObject.create_with_rkpm(
        pts, yms=1e5, prs=0.45, rhos=100, appx_vol=4 / 3 * np.pi * 0.5**3, num_handles=16
    )
    scene = SimplicitsScene()
    idx = scene.add_object(obj)
    scene.set_scene_gravity(acc_gravity=[0, 9.8, 0])
    scene.set_scene_floor(floor_height=0.0, floor_axis=1)
    lowest, centres, kinetic = [], [], []
    previous = scene.get_object_deformed_pts(idx)
    for _ in range(100):
        scene.run_sim_step()
        x = scene.get_object_deformed_pts(idx)
        lowest.append(x[:, 1].min())
        centres.append(x.mean(axis=0))
        # Mean squared point speed: the kinetic energy per unit mass, times 2 (m²/s²).
        kinetic.append(np.mean(np.sum((x - previous) ** 2, axis=1)) / scene.timestep**2)
        previous = x
    # It fell onto the floor (from 0.1 m up) and never sank more than 5 mm into it.
    assert min(lowest) > -5e-3, min(lowest)
    assert max(lowest[-10:]) < 5e-3
    # At rest: over the last ten steps the centre of mass moves less than 1 mm/s and the
    # kinetic energy is below 0.1% of its peak at impact. (What is left is mostly a slow spin
    # about the vertical axis, which backward Euler's O(h²) angular-momentum error leaves at
    # impact and a frictionless floor never damps.)
    centre_speed = np.linalg.norm(np.diff(centres[-11:], axis=0), axis=1) / scene.timestep
    assert centre_speed.max() < 1e-3, centre_speed
    assert max(kinetic[-10:]) < 1e-3 * max(kinetic), (max(kinetic[-10:]), max(kinetic))


class _Tensor:
    """What the front reads of a torch tensor: ``device``, ``detach()`` and ``numpy()``."""

    def __init__(self, values, device):
        self.values = np.asarray(values)
        self.device = type("device", (), {"type": device, "__str__": lambda self: device})()

    def detach(self):
        return self

    def numpy(self):
        return self.values


def test_cpu_tensors_are_read_and_a_cuda_tensor_is_a_clear_error():
    pts = freeform.Geometry.box([0, 0, 0], [1.0, 0.25, 0.25]).integration_points(600).positions
    obj = SimplicitsObject.create_with_rkpm(
        _Tensor(pts, "cpu"), E, NU, RHO, 0.0625, num_handles=4, num_kernels=60
    )
    np.testing.assert_array_equal(obj.pts, pts)
    with pytest.raises(ValueError, match=r"cuda.*tensor\.cpu\(\)"):
        SimplicitsObject.create_with_rkpm(
            _Tensor(pts, "cuda"), E, NU, RHO, 0.0625, num_handles=4, num_kernels=60
        )


def test_kaolins_penalties_are_not_used_and_warned_about_once(bar):
    import warnings

    from freeform import kaolin

    kaolin._WARNED.clear()
    scene = SimplicitsScene()
    idx = scene.add_object(bar)
    with pytest.warns(UserWarning, match="floor_penalty is not used"):
        scene.set_scene_floor(floor_penalty=1e5)
    with pytest.warns(UserWarning, match="bdry_penalty is not used"):
        scene.set_object_boundary_condition(idx, "clamp", lambda x: x[:, 0] < 0.05, bdry_penalty=1e4)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        scene.set_scene_floor(floor_penalty=1e5)
        scene.set_object_boundary_condition(idx, "clamp", lambda x: x[:, 0] < 0.05, bdry_penalty=1e4)
