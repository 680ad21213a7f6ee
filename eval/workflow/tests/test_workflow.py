"""The Snakemake workflow over the quick shapes study on two shapes, with the local executor.

Checks that tasks run side by side, that the merged tables equal a single process's (numbers
outside timing fields), that a second invocation has nothing to do, that deleting one shard
reruns exactly that shape's row and the merge, and that a run interrupted after its first
reference finishes, rerun with --rerun-incomplete, with the same tables.

Environment: FREEFORM_PAPER_BIN (default target/release/freeform-paper).
"""

import json
import os
import pathlib
import shutil
import signal
import subprocess
import sys
import time

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[3]
BIN = pathlib.Path(os.environ.get("FREEFORM_PAPER_BIN", ROOT / "target" / "release" / "freeform-paper")).resolve()
SNAKEFILE = ROOT / "eval" / "workflow" / "Snakefile"
SHAPES = ["37620.stl", "93070.stl"]
LEFT_OUT = ("seconds", "ms_per_step", "cached", "wall", "cache_dir", "meshes", "fem_over")


def numbers(value):
    if isinstance(value, dict):
        return {k: numbers(v) for k, v in value.items() if not any(t in k for t in LEFT_OUT)}
    if isinstance(value, list):
        return [numbers(v) for v in value]
    return value


def snakemake(work, *extra, check=True, background=False):
    command = [
        sys.executable, "-m", "snakemake", "-s", str(SNAKEFILE), "--cores", "2",
        "--directory", str(work), "--rerun-incomplete",
        "--config", f"bin={BIN}", "meshes=meshes", "cache=cache", "out=out",
        "preset=--quick", "threads=1", *extra,
    ]
    if background:
        # Ctrl-C must reach the run even when this test was started in the background, which
        # leaves SIGINT ignored in every child unless reset.
        return subprocess.Popen(
            command, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL),
        )
    run = subprocess.run(command, capture_output=True, text=True)
    if check:
        assert run.returncode == 0, run.stdout + run.stderr
    return run


def tables(folder):
    return [json.loads((folder / f"table{n}.json").read_text()) for n in (2, 7)]


@pytest.fixture(scope="module")
def work(tmp_path_factory):
    if not BIN.exists():
        pytest.fail(f"{BIN} is missing: build it with `cargo build --release -p eval`")
    work = tmp_path_factory.mktemp("workflow")
    (work / "meshes").mkdir()
    for shape in SHAPES:
        shutil.copy(ROOT / "data" / "meshes" / shape, work / "meshes" / shape)
    subprocess.run(
        [BIN, "--quiet", "--out", "single", "--cache", "cache-single", "table", "2", "7", "--quick",
         "--meshes", "meshes", "--json"],
        cwd=work, check=True, capture_output=True, env={**os.environ, "RAYON_NUM_THREADS": "1"},
    )
    return work


def receipts(work):
    return {p.name: json.loads(p.read_text()) for p in (work / "out" / "receipts").glob("*.json")}


def test_the_workflow_runs_tasks_side_by_side_and_merges_the_single_process_tables(work):
    snakemake(work)
    for merged, single in zip(tables(work / "out"), tables(work / "single")):
        assert numbers(merged) == numbers(single), f"table {single['table']}"
    spans = [(r["provenance"]["started"], r["provenance"]["finished"]) for r in receipts(work).values()]
    assert len(spans) == 3 * len(SHAPES), sorted(receipts(work))
    overlapping = any(a[0] < b[1] and b[0] < a[1] for i, a in enumerate(spans) for b in spans[i + 1:])
    assert overlapping, f"no two tasks overlapped: {spans}"
    again = snakemake(work, "-n")
    assert "Nothing to be done" in again.stdout + again.stderr, again.stdout


def test_deleting_one_shard_reruns_exactly_that_row_and_the_merge(work):
    before = {name: r["provenance"]["finished"] for name, r in receipts(work).items()}
    (work / "out" / "shards" / "93070.stl.json").unlink()
    table2 = work / "out" / "table2.md"
    merged_at = table2.stat().st_mtime
    snakemake(work)
    after = {name: r["provenance"]["finished"] for name, r in receipts(work).items()}
    changed = sorted(name for name in after if after[name] != before[name])
    assert changed == ["93070.stl.row.json"], changed
    assert table2.stat().st_mtime > merged_at
    for merged, single in zip(tables(work / "out"), tables(work / "single")):
        assert numbers(merged) == numbers(single)


def test_a_run_interrupted_after_its_first_reference_finishes_the_same_when_rerun(work, tmp_path):
    fresh = tmp_path / "fresh"
    shutil.copytree(work / "meshes", fresh / "meshes")
    run = snakemake(fresh, background=True)
    deadline = time.time() + 300
    while not list((fresh / "out" / "receipts").glob("*.reference.json")):
        assert run.poll() is None, run.stdout.read()
        assert time.time() < deadline, "no reference finished in 5 min"
        time.sleep(0.2)
    run.send_signal(signal.SIGINT)
    run.wait(timeout=120)
    assert not (fresh / "out" / "table2.md").exists(), "the run finished before it was interrupted"
    snakemake(fresh)
    for merged, single in zip(tables(fresh / "out"), tables(work / "single")):
        assert numbers(merged) == numbers(single)


def test_estimates_size_each_reference_task_by_its_largest_system(work):
    plan = subprocess.run(
        [BIN, "--quiet", "--cache", "cache-estimates", "table", "2", "7", "--quick", "--meshes", "meshes",
         "--plan", "--estimate"],
        cwd=work, check=True, capture_output=True, text=True,
    ).stdout
    (work / "plan.json").write_text(plan)
    estimates = json.loads(plan)["estimates"]["references"]
    run = snakemake(work, "out=out-estimates", "estimates=plan.json", "-n")
    asked = {}
    for block in run.stdout.split("rule ")[1:]:
        if not block.startswith("reference:"):
            continue
        shape = block.split("wildcards: shape=")[1].split()[0]
        asked[shape] = int(block.split("mem_mb=")[1].split(",")[0])
    expected = {
        shape: max(
            (e["reference"]["factor_bytes"] + 6000 * e["reference"]["dofs"]) // 1_000_000 + 1000
            for e in estimates
            if e["shape"] == shape
        )
        for shape in SHAPES
    }
    assert asked == expected, run.stdout
