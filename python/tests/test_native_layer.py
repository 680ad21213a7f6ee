"""The boundary between Python and the Rust library: every error is a named class with a
message naming the problem, inputs of any float dtype, layout or list are accepted, outputs are
Rust buffers (or the caller's own array), long calls release the GIL, and Ctrl-C stops a run
between steps with the simulation still usable."""

import os
import pathlib
import signal
import threading
import time
import tracemalloc

import numpy as np
import pytest

import freeform

RUBBER = freeform.Material(1e6, 0.45, 1000.0)
DONUT = pathlib.Path(__file__).resolve().parents[2] / "data" / "splats" / "donut_mipsplatting_fused.ply"


@pytest.fixture(scope="module")
def bar():
    points = freeform.Geometry.box([0, 0, 0], [1.0, 0.25, 0.25]).integration_points(800)
    basis = freeform.build_basis(points, RUBBER, modes=4, kernels=60)
    return points, basis


def falling(points, basis):
    return freeform.Simulation(
        basis,
        points,
        RUBBER,
        scene={"gravity": [0, -9.8, 0]},
        simulation={"quadrature": {"kind": "full"}, "steps": 10},
    )


def test_every_error_class_is_a_freeform_error_naming_the_problem(tmp_path, bar):
    for name in ["GeometryError", "BasisError", "SceneError", "StepError", "FileFormatError"]:
        cls = getattr(freeform, name)
        assert issubclass(cls, freeform.FreeFormError) and issubclass(cls, ValueError), name

    # Missing files: Python's own FileNotFoundError, the path named.
    for read in [
        lambda: freeform.Geometry.read(tmp_path / "missing.obj"),
        lambda: freeform.Basis.load(tmp_path / "missing.basis"),
        lambda: freeform.Splats.read(tmp_path / "missing.ply"),
        lambda: freeform.simulate_scene_file(tmp_path / "missing.toml", tmp_path / "out"),
    ]:
        with pytest.raises(FileNotFoundError, match="missing"):
            read()

    # Files that are not what they claim.
    corrupt = tmp_path / "corrupt.ply"
    corrupt.write_bytes(
        b"ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty float x\nend_header\n\x00"
    )
    with pytest.raises(freeform.FileFormatError, match="corrupt.ply"):
        freeform.Geometry.read(corrupt)
    with pytest.raises(freeform.FileFormatError, match="vertex data"):
        freeform.Splats.read(corrupt)
    garbage = tmp_path / "garbage.basis"
    garbage.write_bytes(b"not a basis")
    with pytest.raises(freeform.FileFormatError, match="not a FreeForm basis file"):
        freeform.Basis.load(garbage)

    # An open mesh; NaN coordinates.
    open_mesh = tmp_path / "open.obj"
    open_mesh.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    with pytest.raises(freeform.GeometryError, match="open"):
        freeform.Geometry.read(open_mesh)
    with pytest.raises(ValueError, match="not finite"):
        freeform.Geometry.from_points([[0.0, 0.0, float("nan")]])

    # m >= K.
    points, basis = bar
    with pytest.raises(freeform.BasisError, match="modes"):
        freeform.build_basis(points, RUBBER, modes=12, kernels=10)

    # A bad setting; a scene file that does not parse.
    with pytest.raises(freeform.SceneError, match="time_step"):
        freeform.Simulation(basis, points, RUBBER, simulation={"time_step": -1.0})
    bad_scene = tmp_path / "bad.toml"
    bad_scene.write_text("[geometry]\nbox = { min = [0, 0, 0] }\n")
    with pytest.raises(freeform.SceneError, match="bad.toml"):
        freeform.simulate_scene_file(bad_scene, tmp_path / "out")

    # A step that fails carries its number; the simulation is still there to inspect.
    sim = falling(points, basis)
    sim.step()
    n = sim.coordinates.shape[0]
    sim.set_state(np.full(n, 1e3), np.zeros(n), sim.time)
    with pytest.raises(freeform.StepError, match="not positive definite") as failed:
        sim.step()
    assert failed.value.step == 2


def test_inputs_of_any_float_dtype_layout_or_list_give_the_same_answer(bar):
    points, basis = bar
    x = np.array([[0.2, 0.1, 0.1], [0.5, 0.12, 0.2], [0.9, 0.2, 0.05]])
    expected = basis.weights(x)
    wide = np.zeros((3, 6))
    wide[:, ::2] = x
    for given in [x.astype(np.float32), np.asfortranarray(x), wide[:, ::2], x.tolist()]:
        got = basis.weights(given)
        # float32 rounds the coordinates by about 1e-8 relative; the weights change by ~1e-6.
        tolerance = 1e-5 if np.asarray(given).dtype == np.float32 else 0.0
        np.testing.assert_allclose(got, basis.weights(np.asarray(given, dtype=np.float64)))
        np.testing.assert_allclose(got, expected, atol=tolerance)
    cloud = freeform.Geometry.from_points(x.astype(np.float32).tolist())
    assert "3 points" in repr(cloud)


def test_outputs_are_rust_buffers_and_out_is_filled_in_place(bar):
    points, basis = bar
    sim = falling(points, basis)
    sim.run(3)
    x = sim.deformed_points()
    # numpy took over the Rust buffer: the array's base is the Rust container, not a copy.
    assert x.base is not None and not isinstance(x.base, np.ndarray)
    assert type(x.base).__name__ == "PySliceContainer"
    out = np.empty_like(x)
    tracemalloc.start()
    try:
        before = tracemalloc.take_snapshot()
        for _ in range(20):
            returned = sim.deformed_points(out=out)
        after = tracemalloc.take_snapshot()
    finally:
        tracemalloc.stop()
    assert returned is out
    np.testing.assert_array_equal(out, x)
    # numpy reports its data allocations to tracemalloc: 20 calls allocate less than one
    # output's worth (what the loop itself allocates is bookkeeping, not arrays).
    grown = sum(s.size_diff for s in after.compare_to(before, "filename"))
    assert grown < x.nbytes, grown
    with pytest.raises(ValueError, match=r"shape"):
        sim.deformed_points(out=np.empty((3, 3)))
    with pytest.raises(ValueError, match="C-contiguous"):
        sim.deformed_points(out=np.empty((x.shape[0], 6))[:, ::2])


def test_building_a_basis_releases_the_gil():
    points = freeform.Geometry.box([0, 0, 0], [1.0, 0.3, 0.3]).integration_points(6000)
    done = threading.Event()

    def build():
        freeform.build_basis(points, RUBBER, modes=16, kernels=600)
        done.set()

    worker = threading.Thread(target=build)
    started = time.perf_counter()
    worker.start()
    iterations = 0
    while not done.is_set():
        iterations += 1
        time.sleep(0)
    worker.join()
    seconds = time.perf_counter() - started
    assert iterations >= 1000, (iterations, seconds)


def test_ctrl_c_stops_a_run_at_the_next_step_and_the_simulation_goes_on(bar):
    points, basis = bar
    sim = falling(points, basis)
    sent = []

    def interrupt():
        sent.append(time.perf_counter())
        os.kill(os.getpid(), signal.SIGINT)

    # A process started in the background (`cmd &`, nohup) inherits SIGINT ignored, and Python
    # then leaves it so: give the test Python's own Ctrl-C handler whatever started it.
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        timer = threading.Timer(0.3, interrupt)
        timer.start()
        with pytest.raises(KeyboardInterrupt):
            sim.run(1_000_000)
        stopped = time.perf_counter()
        timer.join()
    finally:
        signal.signal(signal.SIGINT, previous)
    assert stopped - sent[0] < 0.5
    steps = round(sim.time / 0.01)
    assert steps > 0
    report = sim.step()
    assert report["converged"]
    assert sim.time == pytest.approx((steps + 1) * 0.01, abs=1e-9)


def test_the_type_stubs_name_everything_the_extension_has():
    import ast
    import pathlib

    from freeform import _native

    package = pathlib.Path(freeform.__file__).parent
    assert (package / "py.typed").is_file()
    tree = ast.parse((package / "_native.pyi").read_text())
    stubbed = {}
    for node in tree.body:
        if isinstance(node, ast.ClassDef):
            stubbed[node.name] = {
                n.name for n in node.body if isinstance(n, ast.FunctionDef) and not n.name.startswith("__")
            } | {
                n.target.id
                for n in node.body
                if isinstance(n, ast.AnnAssign) and isinstance(n.target, ast.Name)
            }
        elif isinstance(node, ast.FunctionDef):
            stubbed[node.name] = set()
    public = {name for name in dir(_native) if not name.startswith("_")}
    assert public == set(stubbed), public ^ set(stubbed)
    for name, members in stubbed.items():
        obj = getattr(_native, name)
        if isinstance(obj, type) and not issubclass(obj, BaseException):
            native = {m for m in vars(obj) if not m.startswith("_")}
            assert native == members, (name, native ^ members)


def test_run_reports_progress_at_most_ten_times_a_second_and_always_the_end(bar):
    points, basis = bar
    sim = falling(points, basis)
    calls = []
    # 40 steps of at least 30 ms: about 1.2 s, so about 12 reports, not 40.
    sim.run(
        40,
        on_frame=lambda sim, report: time.sleep(0.03),
        progress=lambda label, done, total: calls.append((label, done, total, time.monotonic())),
    )
    assert calls[-1][:3] == ("simulate", 40, 40)
    assert all(b[3] - a[3] >= 0.099 for a, b in zip(calls[:-2], calls[1:-1]))
    assert 5 <= len(calls) <= 15, len(calls)


def test_a_fixed_thread_count_gives_bit_identical_runs(bar):
    points, basis = bar

    def run(threads):
        # (Every point's quadrature: the automatic one weighs measured times.)
        full = {"quadrature": {"kind": "full"}, "steps": 5}
        scene = freeform.Scene(time_step=0.01, gravity=[0, -9.8, 0], simulation=full, threads=threads)
        k = scene.add_object(basis, points, RUBBER)
        scene.pin(k, {"below": {"axis": 0, "value": 0.05}})
        scene.run(5)
        sim = freeform.Simulation(
            basis, points, RUBBER, scene={"gravity": [0, -9.8, 0]}, simulation=full, threads=threads
        )
        sim.run(5)
        return scene.deformed_points(k), sim.deformed_points()

    for threads in (1, 2):
        first, again = run(threads), run(threads)
        for a, b in zip(first, again):
            np.testing.assert_array_equal(a, b)
    zero = freeform.Scene(threads=0)
    zero.add_object(basis, points, RUBBER)
    with pytest.raises(ValueError, match="at least 1"):
        zero.step()


def test_build_basis_reports_its_three_stages_and_the_end():
    points = freeform.Geometry.box([0, 0, 0], [1.0, 0.25, 0.25]).integration_points(800)
    calls = []
    basis = freeform.build_basis(points, RUBBER, modes=4, kernels=60, progress=lambda *a: calls.append(a))
    assert calls == [
        ("basis: shape functions", 0, 3),
        ("basis: assembly", 1, 3),
        ("basis: eigen solve", 2, 3),
        ("basis", 3, 3),
    ]
    np.testing.assert_array_equal(
        basis.weights(points.positions),
        freeform.build_basis(points, RUBBER, modes=4, kernels=60).weights(points.positions),
    )


def test_a_preview_of_splats_draws_them_with_their_opacity():
    splats = freeform.Splats.read(DONUT)
    image = freeform.render_preview(splats, width=64, height=48)
    assert image.shape == (48, 64, 3) and image.dtype == np.uint8
    assert (image < 250).any() and (image == 255).any()
    clear = freeform.render_preview(splats, opacity=np.zeros(len(splats)), width=64, height=48)
    assert (clear == 255).all()
