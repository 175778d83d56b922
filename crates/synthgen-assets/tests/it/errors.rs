//! Bad input: every error names the problem and ends with the file's path.

use std::path::{Path, PathBuf};

use synthgen_assets::{load_model, write_ply, Error, Units};
use synthgen_core::glam::Vec3;
use synthgen_core::{Model, NoProgress};

fn write(dir: &Path, name: &str, bytes: impl AsRef<[u8]>) -> PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, bytes).unwrap();
    p
}

/// Loads `path`, expecting an error whose message contains `problem` and ends with the path.
fn expect_error(path: &Path, problem: &str) -> Error {
    let err = load_model(path, Units::Auto, &NoProgress).unwrap_err();
    let msg = err.to_string();
    assert!(msg.contains(problem), "{msg:?} should contain {problem:?}");
    assert!(
        msg.ends_with(&path.display().to_string()),
        "{msg:?} should end with the path"
    );
    err
}

const TRI_HEADER: &str = "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\n\
                          property float y\nproperty float z\nelement face 1\n\
                          property list uchar int vertex_indices\nend_header\n";

#[test]
fn empty_files() {
    let dir = tempfile::tempdir().unwrap();
    expect_error(
        &write(dir.path(), "e.ply", ""),
        "malformed ply header, line 1: file is empty",
    );
    expect_error(&write(dir.path(), "e.obj", ""), "mesh has no faces");
    expect_error(&write(dir.path(), "e.gltf", ""), "cannot load gltf");
    expect_error(&write(dir.path(), "e.glb", ""), "cannot load gltf");
}

#[test]
fn missing_file_is_a_read_error() {
    let dir = tempfile::tempdir().unwrap();
    for name in ["nope.ply", "nope.obj", "nope.gltf"] {
        let err = expect_error(&dir.path().join(name), "cannot read file");
        assert!(matches!(err, Error::Read { .. }));
    }
}

#[test]
fn unknown_extension_lists_the_supported_ones() {
    let dir = tempfile::tempdir().unwrap();
    let p = write(dir.path(), "model.stl", "solid x");
    expect_error(
        &p,
        "unsupported model format (supported: ply, obj, gltf, glb)",
    );
    let p = write(dir.path(), "model", "");
    expect_error(&p, "unsupported model format");
}

#[test]
fn face_index_out_of_range() {
    let dir = tempfile::tempdir().unwrap();
    let ply = format!("{TRI_HEADER}0 0 0\n1 0 0\n0 1 0\n3 0 1 3\n");
    expect_error(
        &write(dir.path(), "i.ply", ply),
        "face 0 refers to vertex 3 but the mesh has 3 vertices",
    );
    let neg = format!("{TRI_HEADER}0 0 0\n1 0 0\n0 1 0\n3 0 -1 2\n");
    expect_error(&write(dir.path(), "n.ply", neg), "refers to vertex -1");
    let obj = "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 4\n";
    expect_error(
        &write(dir.path(), "i.obj", obj),
        "face vertex index out of bounds",
    );
}

#[test]
fn nan_vertex() {
    let dir = tempfile::tempdir().unwrap();
    let ply = format!("{TRI_HEADER}0 0 0\n1 nan 0\n0 1 0\n3 0 1 2\n");
    expect_error(
        &write(dir.path(), "nan.ply", ply),
        "vertex 1 has a non-finite coordinate",
    );
    let inf = format!("{TRI_HEADER}0 0 0\n1 0 0\n0 inf 0\n3 0 1 2\n");
    expect_error(
        &write(dir.path(), "inf.ply", inf),
        "vertex 2 has a non-finite coordinate",
    );
    let obj = "v 0 0 0\nv 1 0 0\nv 0 NaN 0\nf 1 2 3\n";
    expect_error(&write(dir.path(), "nan.obj", obj), "non-finite coordinate");
}

#[test]
fn truncated_binary() {
    let dir = tempfile::tempdir().unwrap();
    let full = dir.path().join("full.ply");
    write_ply(&full, &Model::cuboid("c", Vec3::splat(0.1)), 1000.0).unwrap();
    let bytes = std::fs::read(&full).unwrap();
    // 12 faces of 13 bytes at the end: cut into the fourth-last face.
    let cut = write(dir.path(), "cut.ply", &bytes[..bytes.len() - 3 * 13 - 5]);
    expect_error(&cut, "ply body truncated: file ends in face 8 of 12");
    // Cut inside the vertices.
    let header_len = bytes
        .windows(11)
        .position(|w| w == b"end_header\n")
        .unwrap()
        + 11;
    let cut = write(dir.path(), "cutv.ply", &bytes[..header_len + 16 * 3 + 2]);
    expect_error(&cut, "ply body truncated: file ends in vertex 3 of 8");
}

#[test]
fn truncated_ascii() {
    let dir = tempfile::tempdir().unwrap();
    let p = write(dir.path(), "t.ply", format!("{TRI_HEADER}0 0 0\n1 0 0\n"));
    expect_error(&p, "ply body truncated: file ends in vertex 2 of 3");
}

#[test]
fn no_faces() {
    let dir = tempfile::tempdir().unwrap();
    let zero = TRI_HEADER.replace("element face 1", "element face 0");
    expect_error(
        &write(dir.path(), "z.ply", format!("{zero}0 0 0\n1 0 0\n0 1 0\n")),
        "mesh has no faces",
    );
    let cloud = "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\n\
                 property float z\nend_header\n0 0 0\n";
    let err = expect_error(&write(dir.path(), "cloud.ply", cloud), "mesh has no faces");
    assert!(matches!(err, Error::NoFaces { .. }));
    let obj = "v 0 0 0\nv 1 0 0\nv 0 1 0\n";
    expect_error(&write(dir.path(), "pts.obj", obj), "mesh has no faces");
    // Only degenerate faces: skipped, so none left.
    let degenerate = format!("{TRI_HEADER}0 0 0\n1 0 0\n0 1 0\n2 0 1\n");
    expect_error(&write(dir.path(), "d.ply", degenerate), "mesh has no faces");
}

#[test]
fn malformed_headers_and_values_name_the_line() {
    let dir = tempfile::tempdir().unwrap();
    expect_error(
        &write(dir.path(), "a.ply", "solid\n"),
        "line 1: not a ply file",
    );
    let bad_kw = TRI_HEADER.replace("element face 1", "elephant face 1");
    expect_error(
        &write(dir.path(), "b.ply", bad_kw),
        "line 7: unknown keyword \"elephant\"",
    );
    let bad_ty = TRI_HEADER.replace("property float y", "property flot y");
    expect_error(
        &write(dir.path(), "c.ply", bad_ty),
        "line 5: unknown type \"flot\"",
    );
    let no_end = TRI_HEADER.replace("end_header\n", "");
    expect_error(
        &write(dir.path(), "d.ply", no_end),
        "file ends before end_header",
    );
    let big = TRI_HEADER.replace("ascii", "binary_big_endian");
    expect_error(
        &write(dir.path(), "e.ply", big),
        "unsupported ply (binary_big_endian",
    );

    // Header is 9 lines: the second vertex is line 11.
    let short = format!("{TRI_HEADER}0 0 0\n1 0\n0 1 0\n3 0 1 2\n");
    expect_error(
        &write(dir.path(), "f.ply", short),
        "malformed ply vertex 1 (line 11): line ends before property z",
    );
    let long = format!("{TRI_HEADER}0 0 0\n1 0 0\n0 1 0\n3 0 1 2 7\n");
    expect_error(
        &write(dir.path(), "g.ply", long),
        "malformed ply face 0 (line 13): unexpected value \"7\"",
    );
    let word = format!("{TRI_HEADER}0 0 0\n1 zero 0\n0 1 0\n3 0 1 2\n");
    expect_error(
        &write(dir.path(), "h.ply", word),
        "(line 11): invalid float value \"zero\" for y",
    );
    let mut junk = format!("{TRI_HEADER}0 0 0\n1 ").into_bytes();
    junk.extend_from_slice(b"\xff 0\n0 1 0\n3 0 1 2\n");
    expect_error(
        &write(dir.path(), "i.ply", junk),
        "vertex 1 (line 11): invalid float value",
    );
}
