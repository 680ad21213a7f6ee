"""The Python bindings against properties of the method, not their own output: a basis
partitions unity, its weights and gradients agree with finite differences, a free fall is
exact backward Euler, and bad input is a named Python error."""

import json
import os
import pathlib
import subprocess

import numpy as np
import pytest

import freeform

REPO = pathlib.Path(__file__).resolve().parents[2]
RUBBER = freeform.Material(1e6, 0.45, 1000.0)


@pytest.fixture(scope="module")
def bar():
    points = freeform.Geometry.box([0, 0, 0], [1.0, 0.25, 0.25]).integration_points(1500)
    basis = freeform.build_basis(points, RUBBER, modes=6, kernels=120)
    return points, basis


def fall_scene(folder, steps):
    """A scene file of a small rubber box falling freely for `steps` steps of 0.01 s."""
    scene = folder / "fall.toml"
    scene.write_text(
        "[geometry]\nbox = { min = [0, 0, 0], max = [0.4, 0.2, 0.2] }\n"
        "[material]\nyoungs_modulus = 1e5\npoisson_ratio = 0.3\ndensity = 1000\n"
        "[basis]\nmodes = 4\nkernels = 60\npoints = 800\n"
        f"[simulation]\nsteps = {steps}\npoints = 300\nquadrature = {{ kind = \"full\" }}\n"
        "[scene]\ngravity = [0, -9.8, 0]\n"
    )
    return scene


def fall_drop(steps, h=0.01):
    """Backward Euler's free fall from rest: x_n = x_0 - g h² n (n + 1) / 2 (m)."""
    return 9.8 * h**2 * steps * (steps + 1) / 2


def central_differences(function, x, h=1e-6):
    """``∂function/∂x`` at the points ``x`` ``(n, 3)`` by central differences, with the axis of
    the derivative last: ``(n, ..., 3)``."""
    columns = []
    for k in range(3):
        e = np.zeros(3)
        e[k] = h
        columns.append((function(x + e) - function(x - e)) / (2 * h))
    return np.stack(columns, axis=-1)


def cantilever(points, basis):
    """The bar clamped at x <= 0.05 m under gravity, on every point."""
    return freeform.Simulation(
        basis,
        points,
        RUBBER,
        scene={
            "gravity": [0, -9.8, 0],
            "constraints": [{"region": {"below": {"axis": 0, "value": 0.05}}, "motion": "rest"}],
        },
        simulation={"quadrature": {"kind": "full"}},
    )


def test_integration_points_fill_the_box_with_its_volume(bar):
    points, _ = bar
    x = points.positions
    assert x.shape == (len(points), 3) and x.dtype == np.float64
    assert np.all(x >= 0) and np.all(x <= [1.0, 0.25, 0.25])
    assert points.volumes.sum() == pytest.approx(1.0 * 0.25 * 0.25, rel=1e-9)


def test_the_weights_hold_the_constant_handle_and_m_modes(bar):
    points, basis = bar
    w = basis.weights(points.positions)
    assert basis.modes == 6 and basis.handles == 7
    assert w.shape == (len(points), 7)
    np.testing.assert_allclose(w[:, 0], 1.0, atol=1e-12)
    assert np.all(np.diff(basis.eigenvalues) >= 0)
    # The modes are not constant: each varies over the bar.
    assert np.all(w[:, 1:].std(axis=0) > 1e-3)


def test_weight_gradients_match_central_differences(bar):
    _, basis = bar
    rng = np.random.default_rng(0)
    x = rng.uniform([0.2, 0.07, 0.07], [0.8, 0.18, 0.18], size=(5, 3))
    g = basis.weight_gradients(x)
    assert g.shape == (5, 7, 3)
    fd = central_differences(basis.weights, x)
    np.testing.assert_allclose(g, fd, rtol=1e-5, atol=1e-6 * np.abs(fd).max())


def test_a_saved_basis_loads_with_the_same_weights(bar, tmp_path):
    points, basis = bar
    basis.save(tmp_path / "bar.basis")
    again = freeform.Basis.load(tmp_path / "bar.basis")
    np.testing.assert_array_equal(again.weights(points.positions), basis.weights(points.positions))


def test_a_free_fall_scene_is_exact_backward_euler(tmp_path):
    scene = fall_scene(tmp_path, 10)
    summary = freeform.simulate_scene_file(scene, tmp_path / "out")
    assert summary["frames_written"] == 11
    assert summary["unconverged_steps"] == 0
    assert summary["final_max_displacement"] == pytest.approx(fall_drop(10), abs=1e-8)
    assert (tmp_path / "out" / "frame_00010.ply").is_file()


def test_progress_reports_every_step_and_one_thread_falls_as_all_do(tmp_path):
    scene = fall_scene(tmp_path, 6)
    events = []
    summary = freeform.simulate_scene_file(
        scene, tmp_path / "one", threads=1, progress=lambda *e: events.append(e)
    )
    steps = [done for label, done, total in events if label == "simulate"]
    assert steps == list(range(7)), events
    assert any(done is None for _, done, _ in events)  # status lines
    default = freeform.simulate_scene_file(scene, tmp_path / "all")
    for run in (summary, default):
        assert run["final_max_displacement"] == pytest.approx(fall_drop(6), abs=1e-8)
    with pytest.raises(ValueError, match="threads"):
        freeform.simulate_scene_file(scene, tmp_path / "none", threads=0)


def test_a_shipped_scene_file_runs(tmp_path):
    summary = freeform.simulate_scene_file(
        REPO / "freeform" / "examples" / "scenes" / "minimal.toml", tmp_path / "out"
    )
    assert summary["unconverged_steps"] == 0
    assert summary["quadrature"]["choice"] is not None


def test_bad_input_is_a_named_error(tmp_path):
    with pytest.raises(ValueError, match="not finite"):
        freeform.Geometry.from_points(np.array([[0.0, 0.0, np.nan]]))
    with pytest.raises(ValueError, match=r"shape \(n, 3\)"):
        freeform.Geometry.from_points(np.zeros((4, 2)))
    with pytest.raises(ValueError, match="lo < hi"):
        freeform.Geometry.box([0, 0, 0], [0, 1, 1])
    with pytest.raises(ValueError):
        freeform.Material(1e6, 0.5, 1000)
    with pytest.raises(FileNotFoundError, match="no such file"):
        freeform.Geometry.read(tmp_path / "missing.obj")
    with pytest.raises(FileNotFoundError):
        freeform.simulate_scene_file(tmp_path / "missing.toml", tmp_path / "out")
    with pytest.raises(FileNotFoundError):
        freeform.Basis.load(tmp_path / "missing.basis")


def test_a_stepped_free_fall_is_exact_backward_euler(bar):
    points, basis = bar
    sim = freeform.Simulation(
        basis,
        points,
        RUBBER,
        scene={"gravity": [0, -9.8, 0]},
        simulation={"quadrature": {"kind": "full"}, "steps": 10},
    )
    reports = sim.run(10)
    assert all(r["converged"] for r in reports)
    assert sim.time == pytest.approx(0.1, abs=1e-12)
    drop = fall_drop(10)
    x = points.positions
    np.testing.assert_allclose(sim.deformed_points(), x - [0, drop, 0], atol=1e-8)
    corners = np.array([[0.0, 0.0, 0.0], [1.0, 0.25, 0.25]])
    np.testing.assert_allclose(sim.deformed_points(corners), corners - [0, drop, 0], atol=1e-8)
    assert sim.coordinates.shape == (12 * basis.handles,)
    assert sim.quadrature["kind"] == "full"


def test_a_cantilever_holds_its_clamped_end_and_its_tip_sags(bar):
    points, basis = bar
    sim = cantilever(points, basis)
    sim.run(20)
    x = points.positions
    u = sim.deformed_points() - x
    clamped, tip = x[:, 0] <= 0.05, x[:, 0] >= 0.95
    sag = -u[tip, 1].mean()
    assert sag > 0.05, f"tip sag {sag} m"
    # The penalty pins hold the clamped end to within 2% of the tip's sag.
    assert np.abs(u[clamped]).max() < 0.02 * sag
    assert np.isfinite(sim.mechanical_energy)


def test_bad_simulation_settings_are_named_errors(bar):
    points, basis = bar
    with pytest.raises(ValueError, match="time_step"):
        freeform.Simulation(basis, points, RUBBER, simulation={"time_step": -1.0})
    with pytest.raises(ValueError, match="scene"):
        freeform.Simulation(basis, points, RUBBER, scene={"gravity": [0, 1]})
    with pytest.raises(ValueError, match="simulate_scene_file"):
        freeform.Simulation(
            basis, points, RUBBER, simulation={"pins": {"exact": {"inset": 0.01}}}
        )
    with pytest.raises(ValueError):
        freeform.Simulation(basis, points, RUBBER, scene={"gravity": [0, float("nan"), 0]})


def test_deformation_gradients_and_stress_agree_with_differences_and_linear_elasticity(bar):
    points, basis = bar
    sim = cantilever(points, basis)
    sim.run(5)
    rng = np.random.default_rng(1)
    x = rng.uniform([0.1, 0.05, 0.05], [0.9, 0.2, 0.2], size=(6, 3))
    f = sim.deformation_gradients(x)
    assert f.shape == (6, 3, 3)
    np.testing.assert_allclose(f, central_differences(sim.deformed_points, x), atol=1e-7)
    s = sim.stress(x)
    sigma = s["cauchy"]
    assert s["inverted"] == []
    np.testing.assert_allclose(sigma, np.transpose(sigma, (0, 2, 1)), atol=1e-9 * np.abs(sigma).max())
    dev = sigma - np.trace(sigma, axis1=1, axis2=2)[:, None, None] * np.eye(3) / 3
    von_mises = np.sqrt(1.5 * np.einsum("nij,nij->n", dev, dev))
    np.testing.assert_allclose(s["von_mises"], von_mises, rtol=1e-9)
    np.testing.assert_allclose(s["principal"], np.linalg.eigvalsh(sigma)[:, ::-1], rtol=1e-8, atol=1e-6)
    # At small strain every isotropic hyperelastic law has the shear response of linear
    # elasticity, dev σ ≈ 2 μ dev ε (the pressure, λ tr ε at ν = 0.45, also carries λ times
    # the second-order terms of the rotation, so it is not compared).
    E, nu = RUBBER.youngs_modulus, RUBBER.poisson_ratio
    mu = E / (2 * (1 + nu))
    eps = 0.5 * (f + np.transpose(f, (0, 2, 1))) - np.eye(3)
    strain = np.abs(eps).max()
    assert 1e-5 < strain < 0.05, strain
    dev_eps = eps - np.trace(eps, axis1=1, axis2=2)[:, None, None] * np.eye(3) / 3
    linear = 2 * mu * dev_eps
    assert np.abs(dev - linear).max() <= 0.1 * np.abs(linear).max()


DONUT = REPO / "data" / "splats" / "donut_mipsplatting_fused.ply"


def quaternion_matrix(q):
    """Rotation matrices of (w, x, y, z) quaternions, normalized."""
    q = q / np.linalg.norm(q, axis=1, keepdims=True)
    w, x, y, z = q.T
    return np.stack(
        [
            np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], -1),
            np.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], -1),
            np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], -1),
        ],
        1,
    )


def test_splat_covariances_follow_the_files_scales_and_rotations():
    splats = freeform.Splats.read(DONUT)
    n = len(splats)
    assert splats.positions.shape == (n, 3)
    rotation = quaternion_matrix(np.stack([splats.column(f"rot_{k}") for k in range(4)], 1))
    scales = np.exp(2 * np.stack([splats.column(f"scale_{k}") for k in range(3)], 1))
    expected = np.einsum("nij,nj,nkj->nik", rotation, scales, rotation)
    np.testing.assert_allclose(splats.covariances, expected, rtol=1e-6, atol=1e-12)
    packed = splats.packed_covariances
    assert packed.shape == (n, 6)
    upper = splats.covariances[:, [0, 0, 0, 1, 1, 2], [0, 1, 2, 1, 2, 2]]
    np.testing.assert_array_equal(packed, upper)
    with pytest.raises(ValueError, match="no property"):
        splats.column("not_a_property")


def test_deformed_splats_move_their_centres_and_map_covariances_by_f(tmp_path):
    splats = freeform.Splats.read(DONUT)
    x = splats.positions
    geometry = freeform.Geometry.from_points(x)
    points = geometry.integration_points(1500)
    basis = freeform.build_basis(points, RUBBER, modes=6, kernels=120)
    lo = x[:, 0].min()
    sim = freeform.Simulation(
        basis,
        points,
        RUBBER,
        scene={
            "gravity": [0, -9.8, 0],
            "constraints": [
                {"region": {"below": {"axis": 0, "value": float(lo + 0.05 * np.ptp(x[:, 0]))}},
                 "motion": "rest"}
            ],
        },
        simulation={"quadrature": {"kind": "full"}},
    )
    sim.run(5)
    deformed, inverted = sim.deformed_splats(splats)
    assert inverted == 0 and len(deformed) == len(splats)
    np.testing.assert_allclose(deformed.positions, sim.deformed_points(x), atol=1e-6)
    f = sim.deformation_gradients(x)
    mapped = np.einsum("nij,njk,nlk->nil", f, splats.covariances, f)
    scale = np.abs(mapped).max(axis=(1, 2), keepdims=True)
    assert np.abs(deformed.covariances - mapped).max() <= 1e-4 * scale.max()
    # Untouched properties are carried byte for byte, and the written file reads back.
    np.testing.assert_array_equal(deformed.column("opacity"), splats.column("opacity"))
    deformed.write(tmp_path / "deformed.ply")
    again = freeform.Splats.read(tmp_path / "deformed.ply")
    np.testing.assert_array_equal(again.positions, deformed.positions)


def test_frames_of_a_surface_hold_its_deformed_vertices(bar, tmp_path):
    points, basis = bar
    geometry = freeform.Geometry.box([0, 0, 0], [1.0, 0.25, 0.25])
    writer = freeform.FrameWriter(tmp_path / "frames", geometry)
    sim = cantilever(points, basis)
    sim.run(3)
    x = sim.deformed_points(writer.rest_positions)
    ply, vtk = writer.write(3, x, sim.time)
    lines = pathlib.Path(ply).read_text().splitlines()
    assert f"element vertex {len(x)}" in lines and pathlib.Path(vtk).is_file()
    start = lines.index("end_header") + 1
    written = np.array([[float(v) for v in line.split()] for line in lines[start : start + len(x)]])
    np.testing.assert_allclose(written, x, rtol=1e-6, atol=1e-7)  # the PLY holds float32
    with pytest.raises(ValueError, match="display points"):
        writer.write(4, x[:-1], sim.time)


def test_a_preview_draws_the_points_coloured_on_white():
    geometry = freeform.Geometry.box([0, 0, 0], [1.0, 0.25, 0.25])
    x = geometry.integration_points(2000).positions
    image = freeform.render_preview(x, width=200, height=100)
    assert image.shape == (100, 200, 3) and image.dtype == np.uint8
    assert np.all(image[0, 0] == 255)  # the corner is background
    drawn = np.any(image < 250, axis=2)
    assert drawn[40:60, 80:120].mean() > 0.5  # the box fills the middle
    grey = image[drawn]
    assert np.all(np.abs(grey[:, 0].astype(int) - grey[:, 2]) <= 2)  # no values: grey
    coloured = freeform.render_preview(x, values=x[:, 0], width=200, height=100)
    c = coloured[np.any(coloured < 250, axis=2)].astype(int)
    assert np.abs(c[:, 0] - c[:, 2]).max() > 50  # a colour scale, not grey
    with pytest.raises(ValueError, match="values"):
        freeform.render_preview(x, values=[1.0, 2.0])
    with pytest.raises(ValueError, match="up"):
        freeform.render_preview(x, up=[0, 0, 0])


def vtk_points(path):
    """The POINTS of an ASCII VTK file written by FreeForm, ``(n, 3)`` (m)."""
    lines = path.read_text().splitlines()
    start = next(i for i, line in enumerate(lines) if line.startswith("POINTS"))
    count = int(lines[start].split()[1])
    return np.array([[float(v) for v in line.split()] for line in lines[start + 1 : start + 1 + count]])


def test_the_quick_beam_bend_stepped_in_python_equals_the_scene_file_run(tmp_path):
    steps = 20
    scene = {
        "gravity": [0, -9.8, 0],
        "constraints": [{"region": {"below": {"axis": 0, "value": 0.05}}, "motion": "rest"}],
    }
    # A basis built in Python holds by the penalty with the pointwise term; the file says so
    # too (its defaults would build a weighted basis and a pressure space).
    simulation = {
        "steps": steps,
        "simulation_points": 1000,
        "quadrature": {"kind": "full"},
        "pins": "penalty",
        "pressure": "pointwise",
    }
    scene_file = tmp_path / "bend.json"
    scene_file.write_text(
        json.dumps(
            {
                "geometry": {"box": {"min": [0, 0, 0], "max": [1.0, 0.2, 0.2]}},
                "material": {"youngs_modulus": 1e5, "poisson_ratio": 0.45, "density": 1000},
                "basis": {"modes": 6, "kernels": 200, "basis_points": 3000},
                "simulation": simulation,
                "scene": scene,
            }
        )
    )
    # Through the command line when its binary is built (CI builds it before these tests; set
    # FREEFORM_BIN to point at another), else through the library function it calls.
    binary = pathlib.Path(os.environ.get("FREEFORM_BIN", REPO / "target" / "release" / "freeform"))
    if binary.is_file():
        subprocess.run(
            [str(binary), "--quiet", "--out", str(tmp_path / "out"), "simulate", str(scene_file)],
            check=True,
            capture_output=True,
        )
        frames = tmp_path / "out" / "bend"
    else:
        freeform.simulate_scene_file(scene_file, tmp_path / "out")
        frames = tmp_path / "out"

    geometry = freeform.Geometry.box([0, 0, 0], [1.0, 0.2, 0.2])
    material = freeform.Material(1e5, 0.45, 1000)
    basis = freeform.build_basis(geometry.integration_points(3000), material, modes=6, kernels=200)
    sim = freeform.Simulation(
        basis, geometry.integration_points(1000), material, scene=scene, simulation=simulation
    )
    rest = geometry.display_points()
    np.testing.assert_array_equal(vtk_points(frames / "frame_00000.vtk"), rest)
    for k in range(1, steps + 1):
        assert sim.step()["converged"]
        written = vtk_points(frames / f"frame_{k:05d}.vtk")
        np.testing.assert_allclose(sim.deformed_points(rest), written, rtol=0, atol=1e-12)
    # The tip sagged: the frames compared are not the rest state.
    assert written[:, 1].min() < -1e-3


def test_a_scene_of_two_objects_stepped_in_python_equals_the_objects_file_run(tmp_path):
    # A small box dropped onto a larger one resting on the floor, the larger one's left end
    # held; the same scene as a file with [[objects]] and through freeform.Scene.
    steps = 15
    simulation = {
        "steps": steps,
        "simulation_points": 400,
        "time_step": 0.01,
        "quadrature": {"kind": "full"},
        "pins": "penalty",
        "pressure": "pointwise",
    }
    floor = {"normal": [0, 1, 0], "offset": 0.0, "friction": 0.3}
    contact = {"radius": 0.03, "friction": 0.2}
    held = [{"region": {"below": {"axis": 0, "value": 0.05}}, "motion": "rest"}]
    objects = [
        # (name, size, E, position, velocity, constraints)
        ("slab", [0.8, 0.1, 0.3], 1e5, [0.0, 0.0, 0.0], [0.0, 0.0, 0.0], held),
        ("cube", [0.2, 0.2, 0.2], 2e5, [0.3, 0.13, 0.05], [0.0, -0.5, 0.0], []),
    ]
    basis = {"modes": 6, "kernels": 80, "basis_points": 1200}
    scene_file = tmp_path / "stack.json"
    scene_file.write_text(
        json.dumps(
            {
                "simulation": simulation,
                "scene": {"gravity": [0, -9.8, 0], "floor": floor},
                "contact": contact,
                "objects": [
                    {
                        "name": name,
                        "geometry": {"box": {"min": [0, 0, 0], "max": size}},
                        "material": {"youngs_modulus": e, "poisson_ratio": 0.4, "density": 800},
                        "basis": basis,
                        "position": position,
                        "velocity": velocity,
                        "constraints": constraints,
                    }
                    for name, size, e, position, velocity, constraints in objects
                ],
            }
        )
    )
    summary = freeform.simulate_scene_file(scene_file, tmp_path / "out")
    assert summary["unconverged_steps"] == 0

    scene = freeform.Scene(gravity=[0, -9.8, 0], floor=floor, contact=contact, simulation=simulation)
    shapes = []
    for name, size, e, position, velocity, constraints in objects:
        geometry = freeform.Geometry.box([0, 0, 0], size)
        material = freeform.Material(e, 0.4, 800)
        b = freeform.build_basis(geometry.integration_points(basis["basis_points"]), material, modes=6, kernels=80)
        k = scene.add_object(
            b,
            geometry.integration_points(simulation["simulation_points"]),
            material,
            geometry=geometry,
            position=position,
            velocity=velocity,
            constraints=constraints,
        )
        shapes.append((k, name, geometry.display_points()))
    for k, name, rest in shapes:
        written = vtk_points(tmp_path / "out" / name / "frame_00000.vtk")
        np.testing.assert_allclose(scene.deformed_points(k, rest), written, rtol=0, atol=1e-12)
    touched = 0
    for step in range(1, steps + 1):
        report = scene.step()
        assert report["converged"]
        touched = max(touched, report["active_pairs"])
        for k, name, rest in shapes:
            written = vtk_points(tmp_path / "out" / name / f"frame_{step:05d}.vtk")
            np.testing.assert_allclose(scene.deformed_points(k, rest), written, rtol=0, atol=1e-12)
    # The cube came down onto the slab: the objects touched.
    assert touched > 0
    assert scene.time == pytest.approx(steps * 0.01)
    # The point transforms map rest points to their deformed positions (to first order, at
    # the points themselves exactly).
    k, _, rest = shapes[1]
    t = scene.point_transforms(k, rest)
    np.testing.assert_allclose(
        np.einsum("nrc,nc->nr", t[:, :3, :3], rest) + t[:, :3, 3], scene.deformed_points(k, rest), atol=1e-12
    )
    np.testing.assert_array_equal(t[:, 3], np.tile([0, 0, 0, 1.0], (len(rest), 1)))


def test_a_material_at_points_is_the_uniform_one_when_equal_and_stiffens_where_stiffer(bar):
    points, basis = bar
    x = points.positions
    n = len(x)
    scene = {
        "gravity": [0, -9.8, 0],
        "constraints": [{"region": {"below": {"axis": 0, "value": 0.05}}, "motion": "rest"}],
    }

    def tip_sag(material):
        b = freeform.build_basis(points, material, modes=6, kernels=120)
        # Every point: the automatic quadrature's choice depends on how long the steps take.
        full = {"steps": 8, "quadrature": {"kind": "full"}}
        sim = freeform.Simulation(b, points, material, scene=scene, simulation=full)
        sim.run(8)
        return sim.deformed_points(), -sim.deformed_points([[1.0, 0.125, 0.125]])[0, 1] + 0.125

    same = freeform.Material.at_points(x, [1e6] * n, [0.45], [1000.0])
    assert same.per_point and not RUBBER.per_point
    uniform_x, uniform_sag = tip_sag(RUBBER)
    same_x, _ = tip_sag(same)
    np.testing.assert_array_equal(same_x, uniform_x)

    # Ten times stiffer near the clamp (x < 0.5 m): the tip sags less, but more than a bar
    # ten times stiffer everywhere.
    stiff_near_clamp = freeform.Material.at_points(x, np.where(x[:, 0] < 0.5, 1e7, 1e6).tolist(), [0.45], [1000.0])
    _, mixed_sag = tip_sag(stiff_near_clamp)
    _, stiff_sag = tip_sag(freeform.Material(1e7, 0.45, 1000.0))
    assert stiff_sag < mixed_sag < uniform_sag, (stiff_sag, mixed_sag, uniform_sag)
    np.testing.assert_array_equal(stiff_near_clamp.youngs_modulus[:3], np.where(x[:3, 0] < 0.5, 1e7, 1e6))

    # The same part given as a region of the rest shape: the same material at every point.
    cut = 0.5013
    by_points = freeform.Material.at_points(x, np.where(x[:, 0] <= cut, 1e7, 1e6).tolist(), [0.45], [1000.0])
    by_region = freeform.Material(
        1e6, 0.45, 1000.0,
        regions=[{"region": {"below": {"axis": 0, "value": cut}}, "youngs_modulus": 1e7,
                  "poisson_ratio": 0.45, "density": 1000.0}],
    )
    assert by_region.regions == 1
    np.testing.assert_array_equal(tip_sag(by_region)[0], tip_sag(by_points)[0])
    with pytest.raises(freeform.SceneError, match="regions"):
        freeform.Material(1e6, 0.45, 1000.0, regions=[{"region": {"below": {"axis": 0}}}])

    with pytest.raises(ValueError, match="3 values for"):
        freeform.Material.at_points(x, [1e6, 1e6, 1e6], [0.45], [1000.0])
    with pytest.raises(freeform.SceneError, match="point 0"):
        freeform.Material.at_points(x, [-1.0], [0.45], [1000.0])


def test_a_scene_set_up_by_methods_equals_the_one_given_at_construction(bar):
    points, basis = bar
    held = {"below": {"axis": 0, "value": 0.05}}
    full = {"quadrature": {"kind": "full"}}
    given = freeform.Scene(
        time_step=0.01,
        simulation=full,
        gravity=[0, -9.8, 0],
        floor={"normal": [0, 1, 0], "offset": -0.05, "friction": 0.2},
        colliders=[{"shape": {"sphere": {"radius": 0.1}}, "path": [{"time": 0, "translation": [0.7, 0.4, 0.12]}], "friction": 0.0}],
        contact={"radius": 0.03, "friction": 0.0},
    )
    k = given.add_object(basis, points, RUBBER, constraints=[{"region": held, "motion": "rest"}])
    built = freeform.Scene(time_step=0.01, simulation=full)
    j = built.add_object(basis, points, RUBBER)
    built.deformed_points(j)  # a look before stepping does not fix the setup
    built.set_gravity([0, -9.8, 0])
    built.set_floor(offset=-0.05, friction=0.2)
    built.add_collider({"sphere": {"radius": 0.1}}, path=[{"time": 0, "translation": [0.7, 0.4, 0.12]}])
    built.set_contact(radius=0.03)
    built.pin(j, held)
    for _ in range(6):
        assert given.step()["converged"] and built.step()["converged"]
    np.testing.assert_array_equal(given.deformed_points(k), built.deformed_points(j))
    # Pinning by a mask of the same points holds them the same way.
    masked = freeform.Scene(time_step=0.01, gravity=[0, -9.8, 0])
    m = masked.add_object(basis, points, RUBBER)
    masked.pin(m, points.positions[:, 0] <= 0.05)
    masked.run(3)
    np.testing.assert_allclose(
        masked.deformed_points(m)[points.positions[:, 0] <= 0.05],
        points.positions[points.positions[:, 0] <= 0.05],
        atol=1e-3,
    )
    with pytest.raises(freeform.SceneError, match="started"):
        masked.set_gravity([0, 0, 0])


def test_a_mesh_from_arrays_is_checked_closed_and_fills_its_volume():
    vertices = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], dtype=np.float64)
    triangles = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]])
    tetrahedron = freeform.Geometry.from_mesh(vertices, triangles)
    points = tetrahedron.integration_points(4000)
    assert points.volumes.sum() == pytest.approx(1 / 6, rel=0.05)
    with pytest.raises(freeform.GeometryError, match="open"):
        freeform.Geometry.from_mesh(vertices, triangles[:3])


def test_splats_write_back_byte_for_byte_and_at_rest_deform_to_themselves(tmp_path):
    splats = freeform.Splats.read(DONUT)
    splats.write(tmp_path / "copy.ply")
    assert (tmp_path / "copy.ply").read_bytes() == pathlib.Path(DONUT).read_bytes()
    x = splats.positions
    points = freeform.Geometry.from_points(x).integration_points(1500)
    basis = freeform.build_basis(points, RUBBER, modes=6, kernels=120)
    sim = freeform.Simulation(basis, points, RUBBER, simulation={"quadrature": {"kind": "full"}})
    at_rest, inverted = sim.deformed_splats(splats)
    assert inverted == 0
    np.testing.assert_array_equal(at_rest.positions, splats.positions)
    # Scales and rotations are stored as float32 again: each covariance within 1e-5 of its size.
    size = np.abs(splats.covariances).max(axis=(1, 2))
    change = np.abs(at_rest.covariances - splats.covariances).max(axis=(1, 2))
    assert (change <= 1e-5 * size).all(), (change / size).max()
    for name in splats.properties:
        if not name.startswith(("scale_", "rot_")):
            np.testing.assert_array_equal(at_rest.column(name), splats.column(name), err_msg=name)


def test_a_scene_of_one_object_steps_as_the_simulation_and_gives_its_stress_and_splats(bar):
    points, basis = bar
    sim = cantilever(points, basis)
    scene = freeform.Scene(
        time_step=0.01, gravity=[0, -9.8, 0], simulation={"quadrature": {"kind": "full"}}
    )
    k = scene.add_object(basis, points, RUBBER)
    scene.pin(k, {"below": {"axis": 0, "value": 0.05}})
    sim.run(4)
    scene.run(4)
    np.testing.assert_array_equal(scene.deformed_points(k), sim.deformed_points())
    x = np.array([[0.5, 0.1, 0.1], [0.9, 0.2, 0.05]])
    for key in ("cauchy", "principal", "von_mises"):
        np.testing.assert_array_equal(scene.stress(k, x)[key], sim.stress(x)[key])
    splats = freeform.Splats.read(DONUT)
    moved, _ = scene.deformed_splats(k, splats)
    # (The splat table keeps its centres as float32.)
    np.testing.assert_allclose(moved.positions, sim.deformed_points(splats.positions), atol=1e-6)


def test_scene_frames_are_written_where_the_scene_file_run_puts_them(tmp_path, bar):
    points, basis = bar
    scene = freeform.Scene(time_step=0.01, gravity=[0, -9.8, 0], quadrature={"kind": "full"})
    box = freeform.Geometry.box([0, 0, 0], [1.0, 0.25, 0.25])
    k = scene.add_object(basis, points, RUBBER, geometry=box, name="bar")
    c = scene.add_object(basis, points, RUBBER, position=[0, 1, 0])
    scene.run(2)
    files = scene.write_frame(tmp_path, 2)
    assert [pathlib.Path(f[1]).relative_to(tmp_path).as_posix() for f in files] == [
        "bar/frame_00002.vtk",
        "object1/frame_00002.vtk",
    ]
    np.testing.assert_allclose(
        vtk_points(tmp_path / "bar" / "frame_00002.vtk"), scene.deformed_points(k, box.display_points()), atol=0
    )
    assert vtk_points(tmp_path / "object1" / "frame_00002.vtk").shape == (len(points), 3)
    assert c == 1
