//! Bounded fuzzing of the geometry readers (proptest over bytes): valid files in every format
//! with random byte edits, truncations and splices, plus raw bytes behind each format's header.
//! Whatever the bytes, a reader returns (never panics), and what it accepts is valid: finite
//! coordinates, and for meshes a closed, outward-oriented surface (checked by `TriangleMesh`).
//!
//! 256 cases per format per run (a few seconds); failures are saved under
//! `proptest-regressions/` and replayed first.

use std::path::Path;

use proptest::prelude::*;
use rkpm_core::{GeometryFormat, parse_point_cloud, parse_triangle_mesh};

const TETRA_OBJ: &str = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n";

const TETRA_PLY: &str = "ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\n\
property float z\nelement face 4\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n\
0 1 0\n0 0 1\n3 0 2 1\n3 0 1 3\n3 0 3 2\n3 1 2 3\n";

/// A binary STL of the unit corner tetrahedron.
fn tetra_stl() -> Vec<u8> {
    let v = [
        [0.0f32, 0.0, 0.0],
        [1.0, 0.0, 0.0],
        [0.0, 1.0, 0.0],
        [0.0, 0.0, 1.0],
    ];
    let faces = [[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]];
    let mut bytes = vec![0u8; 80];
    bytes.extend(4u32.to_le_bytes());
    for f in faces {
        bytes.extend([0u8; 12]); // normal
        for i in f {
            for c in v[i] {
                bytes.extend(c.to_le_bytes());
            }
        }
        bytes.extend([0u8; 2]);
    }
    bytes
}

/// A binary little-endian PLY cloud of `n` points.
fn cloud_ply(n: usize) -> Vec<u8> {
    let mut bytes = format!(
        "ply\nformat binary_little_endian 1.0\nelement vertex {n}\nproperty float x\n\
         property float y\nproperty float z\nproperty float opacity\nend_header\n"
    )
    .into_bytes();
    for i in 0..n {
        for c in [i as f32, 0.5, -1.0, 0.1] {
            bytes.extend(c.to_le_bytes());
        }
    }
    bytes
}

/// An edit of a valid file: overwrite a byte, truncate, or splice random bytes in.
#[derive(Clone, Debug)]
enum Edit {
    Set(usize, u8),
    Truncate(usize),
    Splice(usize, Vec<u8>),
}

fn edits() -> impl Strategy<Value = Vec<Edit>> {
    prop::collection::vec(
        prop_oneof![
            (any::<usize>(), any::<u8>()).prop_map(|(i, b)| Edit::Set(i, b)),
            any::<usize>().prop_map(Edit::Truncate),
            (any::<usize>(), prop::collection::vec(any::<u8>(), 1..16))
                .prop_map(|(i, b)| Edit::Splice(i, b)),
        ],
        1..6,
    )
}

fn apply(mut bytes: Vec<u8>, edits: &[Edit]) -> Vec<u8> {
    for edit in edits {
        let len = bytes.len().max(1);
        match edit {
            Edit::Set(i, b) => {
                if !bytes.is_empty() {
                    bytes[i % len] = *b;
                }
            }
            Edit::Truncate(i) => bytes.truncate(i % len),
            Edit::Splice(i, b) => {
                let at = i % len.min(bytes.len() + 1).max(1);
                let at = at.min(bytes.len());
                bytes.splice(at..at, b.iter().copied());
            }
        }
    }
    bytes
}

/// Parses as a mesh; an accepted mesh must be finite (closedness is `TriangleMesh::new`'s).
fn check_mesh(bytes: &[u8], format: GeometryFormat) {
    if let Ok(mesh) = parse_triangle_mesh(bytes, format, Path::new("fuzz")) {
        assert!(
            mesh.vertices()
                .iter()
                .all(|v| v.iter().all(|c| c.is_finite()))
        );
        assert!(mesh.volume() > 0.0, "accepted meshes are outward-oriented");
    }
}

proptest! {
    // 256 cases per property unless `PROPTEST_CASES` asks for a longer run.
    #![proptest_config(ProptestConfig {
        cases: std::env::var("PROPTEST_CASES")
            .ok()
            .and_then(|v| v.parse().ok())
            .unwrap_or(256),
        ..ProptestConfig::default()
    })]

    #[test]
    fn edited_obj_files_never_panic(e in edits()) {
        check_mesh(&apply(TETRA_OBJ.as_bytes().to_vec(), &e), GeometryFormat::Obj);
    }

    #[test]
    fn edited_stl_files_never_panic(e in edits()) {
        check_mesh(&apply(tetra_stl(), &e), GeometryFormat::Stl);
    }

    #[test]
    fn edited_ply_meshes_never_panic(e in edits()) {
        check_mesh(&apply(TETRA_PLY.as_bytes().to_vec(), &e), GeometryFormat::Ply);
    }

    #[test]
    fn edited_ply_clouds_never_panic_and_accepted_points_are_finite(
        n in 1usize..20,
        e in edits(),
    ) {
        let bytes = apply(cloud_ply(n), &e);
        if let Ok(cloud) = parse_point_cloud(&bytes, Path::new("fuzz.ply")) {
            prop_assert!(!cloud.is_empty());
            prop_assert!(cloud.positions().iter().all(|p| p.iter().all(|c| c.is_finite())));
        }
    }

    #[test]
    fn raw_bytes_behind_a_header_never_panic(
        tail in prop::collection::vec(any::<u8>(), 0..400),
        which in 0usize..4,
    ) {
        let header: &[u8] = match which {
            0 => b"ply\nformat binary_little_endian 1.0\nelement vertex 7\nproperty float x\nproperty float y\nproperty float z\nelement face 3\nproperty list uchar int vertex_indices\nend_header\n",
            1 => b"ply\nformat binary_big_endian 1.0\nelement vertex 3\nproperty double x\nproperty double y\nproperty double z\nend_header\n",
            2 => b"solid fuzz\n",
            _ => b"v 0 0 0\nf ",
        };
        let mut bytes = header.to_vec();
        bytes.extend(tail);
        let format = match which {
            0 | 1 => GeometryFormat::Ply,
            2 => GeometryFormat::Stl,
            _ => GeometryFormat::Obj,
        };
        check_mesh(&bytes, format);
        let _ = parse_point_cloud(&bytes, Path::new("fuzz.ply"));
    }
}

#[test]
fn the_unedited_fuzz_seeds_are_valid_files() {
    // Otherwise the fuzzing would only ever exercise error paths.
    for (bytes, format) in [
        (TETRA_OBJ.as_bytes().to_vec(), GeometryFormat::Obj),
        (tetra_stl(), GeometryFormat::Stl),
        (TETRA_PLY.as_bytes().to_vec(), GeometryFormat::Ply),
    ] {
        let mesh = parse_triangle_mesh(&bytes, format, Path::new("seed")).unwrap();
        assert!((mesh.volume() - 1.0 / 6.0).abs() < 1e-6, "{format:?}");
    }
    assert_eq!(
        parse_point_cloud(&cloud_ply(5), Path::new("seed.ply"))
            .unwrap()
            .len(),
        5
    );
}
