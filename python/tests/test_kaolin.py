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
    scene = SimplicitsScene(timestep=0.01)
    idx = scene.add_object(bar)
    scene.set_scene_gravity()
    scene.set_scene_floor(floor_height=-0.05, floor_axis=1)
    scene.set_object_boundary_condition(idx, "clamp", lambda x: x[:, 0] <= 0.05, bdry_penalty=1e4)
    for _ in range(8):
        scene.run_sim_step()
    sim = freeform.Simulation(
        bar.basis,
        bar.points,
        bar.material,
        scene={"gravity": [0, -9.8, 0], "floor": {"normal": [0, 1, 0], "offset": -0.05}},
        simulation={"time_step": 0.01},
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


def test_what_the_front_does_not_support_is_a_named_error(bar):
    pts = bar.pts
    with pytest.raises(NotImplementedError, match="yms"):
        SimplicitsObject.create_with_rkpm(pts, np.linspace(1e5, 1e6, len(pts)), NU, RHO, 0.0625)
    scene = SimplicitsScene()
    idx = scene.add_object(bar)
    with pytest.raises(ValueError, match="selects none"):
        scene.set_object_boundary_condition(idx, "none", lambda x: x[:, 0] < -1.0)
    with pytest.raises(ValueError, match="floor_axis"):
        scene.set_scene_floor(floor_axis=3)
