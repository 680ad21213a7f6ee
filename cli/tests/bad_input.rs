//! Bad input through the `freeform` binary: each case exits non-zero with one line naming the
//! input and the problem, and leaves no file that looks like a result.

use std::path::{Path, PathBuf};
use std::process::Command;

const TETRA: &str = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n";

fn scratch(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("freeform-bad-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// Runs `freeform basis FILE ARGS… --save DIR/out.basis` and checks the failure contract:
/// non-zero exit, a single `error:` line containing every `expected` fragment, no basis file.
fn basis_fails(dir: &Path, file: &Path, args: &[&str], expected: &[&str]) {
    let save = dir.join("out.basis");
    let run = Command::new(env!("CARGO_BIN_EXE_freeform"))
        .args(["--quiet", "--out"])
        .arg(dir.join("out"))
        .arg("basis")
        .arg(file)
        .args(args)
        .arg("--save")
        .arg(&save)
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert!(!run.status.success(), "{file:?} {args:?} succeeded");
    let lines: Vec<&str> = stderr.lines().collect();
    assert_eq!(lines.len(), 1, "one line, got: {stderr}");
    assert!(lines[0].starts_with("error: "), "{stderr}");
    for fragment in expected {
        assert!(lines[0].contains(fragment), "{fragment:?} not in: {stderr}");
    }
    assert!(!save.exists(), "a basis file was left behind");
}

fn write(dir: &Path, name: &str, bytes: &[u8]) -> PathBuf {
    let path = dir.join(name);
    std::fs::write(&path, bytes).unwrap();
    path
}

#[test]
fn unreadable_geometry_files_are_named_errors_that_write_nothing() {
    let dir = scratch("files");
    basis_fails(
        &dir,
        &dir.join("absent.obj"),
        &[],
        &["absent.obj", "no such file"],
    );
    basis_fails(
        &dir,
        &write(&dir, "empty.obj", b""),
        &[],
        &["empty.obj", "no faces"],
    );
    let nan = TETRA.replace("v 1 0 0", "v NaN 0 0");
    basis_fails(
        &dir,
        &write(&dir, "nan.obj", nan.as_bytes()),
        &[],
        &["nan.obj", "non-finite"],
    );
    let inf = TETRA.replace("v 0 1 0", "v 0 inf 0");
    basis_fails(
        &dir,
        &write(&dir, "inf.obj", inf.as_bytes()),
        &[],
        &["inf.obj", "non-finite"],
    );
    let open = TETRA.replace("f 2 3 4\n", "");
    basis_fails(
        &dir,
        &write(&dir, "open.obj", open.as_bytes()),
        &[],
        &["open.obj", "open"],
    );
    // An open PLY mesh is an error, not a point cloud of its vertices.
    let open_ply = "ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\n\
        property float z\nelement face 3\nproperty list uchar int vertex_indices\nend_header\n\
        0 0 0\n1 0 0\n0 1 0\n0 0 1\n3 0 2 1\n3 0 1 3\n3 0 3 2\n";
    basis_fails(
        &dir,
        &write(&dir, "open.ply", open_ply.as_bytes()),
        &[],
        &["open.ply", "open"],
    );
    let truncated =
        &std::fs::read(test_support::fixtures::shared_mesh("32770.stl")).unwrap()[..500];
    basis_fails(
        &dir,
        &write(&dir, "cut.stl", truncated),
        &[],
        &["cut.stl", "STL"],
    );
    let mut corrupt =
        b"ply\nformat binary_little_endian 1.0\nelement vertex 100\nproperty float x\n\
        property float y\nproperty float z\nend_header\n"
            .to_vec();
    corrupt.extend([0x7f; 37]);
    basis_fails(
        &dir,
        &write(&dir, "corrupt.ply", &corrupt),
        &[],
        &["corrupt.ply"],
    );
    basis_fails(
        &dir,
        &write(&dir, "mesh.txt", TETRA.as_bytes()),
        &[],
        &["mesh.txt", "unsupported"],
    );
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn absurd_parameters_are_named_errors_that_write_nothing() {
    let dir = scratch("params");
    let mesh = test_support::fixtures::shared_mesh("bunny.obj");
    let small = ["--points", "3000"];
    basis_fails(
        &dir,
        &mesh,
        &[&small[..], &["--young=-5"]].concat(),
        &["Young", "-5"],
    );
    basis_fails(
        &dir,
        &mesh,
        &[&small[..], &["--poisson", "0.5"]].concat(),
        &["Poisson", "0.5"],
    );
    basis_fails(
        &dir,
        &mesh,
        &[&small[..], &["--young", "NaN"]].concat(),
        &["Young"],
    );
    basis_fails(
        &dir,
        &mesh,
        &[&small[..], &["--modes", "60", "--kernels", "50"]].concat(),
        &["60"],
    );
    basis_fails(
        &dir,
        &mesh,
        &[&small[..], &["--kernels", "5000"]].concat(),
        &["5000"],
    );
    basis_fails(&dir, &mesh, &["--points", "0"], &["points"]);
    let _ = std::fs::remove_dir_all(&dir);
}
