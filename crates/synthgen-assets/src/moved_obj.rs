//! A scan written moved (`synthgen model align`): the OBJ with its positions and normals
//! transformed, its material libraries and the textures they name copied beside it.
//!
//! The names inside an OBJ and its MTL are untrusted: `mtllib ../../x.mtl` or
//! `map_Kd /home/me/scan/tex.png` must not decide where we write. Every file goes into the
//! output folder, under its own name when that is a plain relative path, else under its file
//! name (made unique), and the reference in the copied OBJ / MTL is rewritten to match. The
//! output folder may not be, nor contain, any file the scan reads, so no input is ever opened
//! for writing, and every file is written atomically.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use synthgen_core::glam::{DMat3, DMat4, DVec3};
use synthgen_core::paths::{overlap, plain_relative, resolve};

use crate::obj::texture_file_name;
use crate::Error;

/// The keys of an MTL line that name a texture file.
fn is_texture_key(key: &str) -> bool {
    key.starts_with("map_") || matches!(key, "bump" | "disp" | "norm" | "decal" | "refl")
}

/// One file to write, relative to the output folder.
enum Content {
    Bytes(Vec<u8>),
    CopyOf(PathBuf),
}

/// Everything a moved scan writes, and everything it reads, before anything is written.
struct Plan {
    /// The scan, its material libraries and their textures (as read).
    inputs: Vec<PathBuf>,
    /// (name inside the output folder, content), the OBJ first.
    files: Vec<(PathBuf, Content)>,
}

/// The names the plan has given out: name → the source written under it.
#[derive(Default)]
struct Names(BTreeMap<PathBuf, PathBuf>);

impl Names {
    /// Where `source` (named `name` in a file) goes inside the output folder: `name` itself
    /// when it is a plain relative path, else its file name; a name another source already
    /// has gets `_2`, `_3`, ... before its extension.
    fn assign(&mut self, name: &str, source: &Path) -> PathBuf {
        let wanted = plain_relative(name).unwrap_or_else(|| {
            Path::new(name)
                .file_name()
                .and_then(|f| plain_relative(&f.to_string_lossy()))
                .unwrap_or_else(|| PathBuf::from("file"))
        });
        let key = resolve(source);
        let mut candidate = wanted.clone();
        for n in 2.. {
            match self.0.get(&candidate) {
                None => {
                    self.0.insert(candidate.clone(), key);
                    return candidate;
                }
                Some(s) if *s == key => return candidate,
                Some(_) => {
                    let stem = wanted
                        .file_stem()
                        .map(|s| s.to_string_lossy().into_owned())
                        .unwrap_or_default();
                    let file = match wanted.extension() {
                        Some(e) => format!("{stem}_{n}.{}", e.to_string_lossy()),
                        None => format!("{stem}_{n}"),
                    };
                    candidate = wanted.with_file_name(file);
                }
            }
        }
        unreachable!("the loop above returns")
    }
}

/// `path` as written in an OBJ / MTL (forward slashes).
fn as_reference(path: &Path) -> String {
    path.to_string_lossy().replace('\\', "/")
}

fn plan(src: &Path, m: DMat4) -> Result<Plan, Error> {
    let read = |path: &Path, e: std::io::Error| Error::Read {
        path: path.to_path_buf(),
        source: e,
    };
    let text = std::fs::read_to_string(src).map_err(|e| read(src, e))?;
    let dir = src.parent().unwrap_or(Path::new("."));
    let normal_m = DMat3::from_mat4(m).inverse().transpose();
    let mut names = Names::default();
    let obj_name = PathBuf::from(src.file_name().unwrap_or_default());
    names.assign(&obj_name.to_string_lossy(), src);
    let mut inputs = vec![src.to_path_buf()];
    let mut files = Vec::new();
    let mut out = String::with_capacity(text.len());
    let mut mtllibs: Vec<(PathBuf, PathBuf)> = Vec::new(); // (source, name in the output)
    for (n, line) in text.lines().enumerate() {
        let t = line.trim_start();
        let mut parts = t.split_ascii_whitespace();
        match parts.next() {
            Some(kind @ ("v" | "vn")) => {
                let nums: Vec<&str> = parts.collect();
                let xyz: Option<Vec<f64>> =
                    nums.iter().take(3).map(|s| s.parse::<f64>().ok()).collect();
                let xyz = xyz.filter(|v| v.len() == 3 && v.iter().all(|x| x.is_finite()));
                if xyz.is_none() && kind == "vn" {
                    // Scans ship NaN normals (YCB's tuna can and mug); readers replace them.
                    out.push_str(line);
                    out.push('\n');
                    continue;
                }
                let Some(xyz) = xyz else {
                    return Err(Error::Obj {
                        reason: format!("line {}: `{kind}` needs three finite numbers", n + 1),
                        path: src.to_path_buf(),
                    });
                };
                let p = DVec3::new(xyz[0], xyz[1], xyz[2]);
                let q = if kind == "v" {
                    m.transform_point3(p)
                } else {
                    (normal_m * p).normalize_or_zero()
                };
                out.push_str(&format!("{kind} {:.9} {:.9} {:.9}", q.x, q.y, q.z));
                for rest in &nums[3..] {
                    out.push(' ');
                    out.push_str(rest);
                }
                out.push('\n');
            }
            Some("mtllib") => {
                let mut refs = Vec::new();
                for lib in parts {
                    let source = dir.join(lib);
                    let name = names.assign(lib, &source);
                    refs.push(as_reference(&name));
                    if !mtllibs.iter().any(|(s, _)| *s == source) {
                        mtllibs.push((source, name));
                    }
                }
                out.push_str("mtllib ");
                out.push_str(&refs.join(" "));
                out.push('\n');
            }
            _ => {
                out.push_str(line);
                out.push('\n');
            }
        }
    }
    files.push((obj_name, Content::Bytes(out.into_bytes())));
    for (mtl, mtl_name) in mtllibs {
        let mtl_text = std::fs::read_to_string(&mtl).map_err(|e| read(&mtl, e))?;
        inputs.push(mtl.clone());
        let mut copied = String::with_capacity(mtl_text.len());
        for l in mtl_text.lines() {
            let t = l.trim_start();
            let texture = t
                .split_once(char::is_whitespace)
                .filter(|(key, _)| is_texture_key(key))
                .and_then(|(key, value)| texture_file_name(value).map(|tex| (key, value, tex)));
            let Some((key, value, tex)) = texture else {
                copied.push_str(l);
                copied.push('\n');
                continue;
            };
            let source = dir.join(&tex);
            if !source.is_file() {
                return Err(Error::Read {
                    path: source,
                    source: std::io::Error::new(
                        std::io::ErrorKind::NotFound,
                        format!("a texture {} names", mtl.display()),
                    ),
                });
            }
            let name = names.assign(&tex, &source);
            if !inputs.iter().any(|i| resolve(i) == resolve(&source)) {
                inputs.push(source.clone());
                files.push((name.clone(), Content::CopyOf(source)));
            }
            if name == Path::new(&tex) {
                copied.push_str(l);
            } else {
                // The options before the name (`-bm 0.2 -clamp on`) stay.
                let value = value.trim();
                let options = if value.starts_with('-') {
                    value
                        .rsplit_once(char::is_whitespace)
                        .map_or("", |(o, _)| o)
                } else {
                    ""
                };
                copied.push_str(key);
                copied.push(' ');
                if !options.is_empty() {
                    copied.push_str(options);
                    copied.push(' ');
                }
                copied.push_str(&as_reference(&name));
            }
            copied.push('\n');
        }
        files.push((mtl_name, Content::Bytes(copied.into_bytes())));
    }
    Ok(Plan { inputs, files })
}

/// The files the OBJ `src` reads: itself, its material libraries and the textures they name
/// (as [`write_moved_obj`] copies them), for a caller's check that its outputs stay apart
/// from them.
pub fn obj_inputs(src: &Path) -> Result<Vec<PathBuf>, Error> {
    Ok(plan(src, DMat4::IDENTITY)?.inputs)
}

/// Writes the OBJ file `src` moved by `m` (`p' = m · p` in the file's own units) into `out_dir`
/// under its own name, with its material files and the textures they name copied beside it:
/// `v` positions and `vn` normals are transformed, every other line (UVs, faces, groups,
/// materials, per-vertex colours after the position) is kept as it is, but for a file name
/// that is not a plain relative path (absolute, or with `..`), which is written under its
/// file name instead and renamed in the copy. Returns the files written. Texture names are
/// read as [`load_model`](crate::load_model) reads them (options, backslashes and trailing
/// spaces allowed); a missing texture is an error naming it. An `out_dir` that is or contains
/// one of the files read is refused before anything is written.
pub fn write_moved_obj(src: &Path, out_dir: &Path, m: DMat4) -> Result<Vec<PathBuf>, Error> {
    let plan = plan(src, m)?;
    for input in &plan.inputs {
        if let Some(o) = overlap(out_dir, input) {
            return Err(Error::OutputOverInput {
                relation: o.verb(),
                input: input.clone(),
                path: out_dir.to_path_buf(),
            });
        }
    }
    let write_err = |path: &Path, e: std::io::Error| Error::Write {
        path: path.to_path_buf(),
        source: e,
    };
    std::fs::create_dir_all(out_dir).map_err(|e| write_err(out_dir, e))?;
    let root = resolve(out_dir);
    let mut written = Vec::with_capacity(plan.files.len());
    for (name, content) in plan.files {
        let dst = out_dir.join(&name);
        if let Some(p) = dst.parent() {
            std::fs::create_dir_all(p).map_err(|e| write_err(p, e))?;
        }
        // A folder inside the output that is a link elsewhere does not take the file there.
        let at = resolve(&dst);
        if !at.starts_with(&root) || plan.inputs.iter().any(|i| resolve(i) == at) {
            return Err(Error::OutputOverInput {
                relation: "would overwrite",
                input: at,
                path: dst,
            });
        }
        let bytes = match content {
            Content::Bytes(b) => b,
            Content::CopyOf(from) => std::fs::read(&from).map_err(|e| Error::Read {
                path: from.clone(),
                source: e,
            })?,
        };
        synthgen_core::atomic::write_atomic(&dst, &bytes, false)
            .map_err(|(_, e)| write_err(&dst, e))?;
        written.push(dst);
    }
    Ok(written)
}

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::expect_used)]
mod tests {
    use super::*;
    use synthgen_core::glam::{DMat3, DQuat};

    fn moved() -> DMat4 {
        DMat4::from_rotation_translation(
            DQuat::from_mat3(&DMat3::from_rotation_z(std::f64::consts::FRAC_PI_2)),
            DVec3::new(0.0, 0.0, 2.0),
        )
    }

    /// Positions and normals move, everything else is kept; the MTL and the texture it names
    /// (with a trailing space, as YCB ships it) are copied; NaN normals are left for readers.
    #[test]
    fn a_moved_obj_keeps_its_uvs_faces_and_textures() {
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path();
        std::fs::write(
            d.join("a.obj"),
            "# scan\nmtllib a.mtl\nv 1 0 0 0.5 0.5 0.5\nv 0 1 0\nv 0 0 1\nvt 0.1 0.2\nvn 1 0 0\nvn nan nan nan\nusemtl m\nf 1/1/1 2/1/1 3/1/2\n",
        )
        .unwrap();
        std::fs::write(d.join("a.mtl"), "newmtl m\nmap_Kd tex.png \n").unwrap();
        std::fs::write(d.join("tex.png"), b"png").unwrap();
        let out = d.join("out");
        let written = write_moved_obj(&d.join("a.obj"), &out, moved()).unwrap();
        assert_eq!(written.len(), 3);
        let text = std::fs::read_to_string(out.join("a.obj")).unwrap();
        let lines: Vec<&str> = text.lines().collect();
        assert_eq!(lines[0], "# scan");
        assert_eq!(lines[1], "mtllib a.mtl");
        assert_eq!(
            lines[2],
            "v 0.000000000 1.000000000 2.000000000 0.5 0.5 0.5"
        );
        assert_eq!(lines[5], "vt 0.1 0.2");
        assert_eq!(lines[6], "vn 0.000000000 1.000000000 0.000000000");
        assert_eq!(lines[7], "vn nan nan nan");
        assert_eq!(lines[9], "f 1/1/1 2/1/1 3/1/2");
        assert_eq!(std::fs::read(out.join("tex.png")).unwrap(), b"png");
        assert_eq!(
            std::fs::read_to_string(out.join("a.mtl")).unwrap(),
            "newmtl m\nmap_Kd tex.png \n"
        );
        // A missing texture is an error naming it.
        std::fs::remove_file(d.join("tex.png")).unwrap();
        let e = write_moved_obj(&d.join("a.obj"), &d.join("out2"), moved()).unwrap_err();
        assert!(e.to_string().contains("tex.png"), "{e}");
    }

    /// Regression (issue 50): `map_Kd ../../x.png` was copied to OUT/../../x.png, and a name
    /// that led back to its own source (absolute, or `..` onto the same file) was copied onto
    /// itself and truncated to 0 bytes.
    #[test]
    fn names_that_leave_the_scan_folder_are_written_inside_the_output_and_sources_are_untouched() {
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path();
        let scan = d.join("scans/drill");
        std::fs::create_dir_all(&scan).unwrap();
        std::fs::create_dir_all(d.join("elsewhere")).unwrap();
        std::fs::write(d.join("elsewhere/far.png"), b"far").unwrap();
        std::fs::write(scan.join("tex.png"), b"tex").unwrap();
        std::fs::write(d.join("shared.mtl"), "newmtl s\nKd 1 1 1\n").unwrap();
        let abs = scan.join("tex.png");
        std::fs::write(
            scan.join("a.mtl"),
            format!(
                "newmtl m\nmap_Kd ../../elsewhere/far.png\nmap_Ks -bm 0.5 {}\nmap_Bump ../drill/tex.png\n",
                abs.display()
            ),
        )
        .unwrap();
        std::fs::write(
            scan.join("a.obj"),
            "mtllib a.mtl ../../shared.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n",
        )
        .unwrap();
        let out = d.join("out");
        let before: Vec<(PathBuf, Vec<u8>)> = [
            d.join("elsewhere/far.png"),
            scan.join("tex.png"),
            scan.join("a.mtl"),
            d.join("shared.mtl"),
        ]
        .into_iter()
        .map(|p| (p.clone(), std::fs::read(&p).unwrap()))
        .collect();
        let written = write_moved_obj(&scan.join("a.obj"), &out, moved()).unwrap();
        for w in &written {
            assert!(resolve(w).starts_with(resolve(&out)), "{}", w.display());
        }
        for (p, bytes) in &before {
            assert_eq!(&std::fs::read(p).unwrap(), bytes, "{} changed", p.display());
        }
        assert_eq!(std::fs::read(out.join("far.png")).unwrap(), b"far");
        assert_eq!(std::fs::read(out.join("tex.png")).unwrap(), b"tex");
        let obj = std::fs::read_to_string(out.join("a.obj")).unwrap();
        assert!(obj.starts_with("mtllib a.mtl shared.mtl\n"), "{obj}");
        let mtl = std::fs::read_to_string(out.join("a.mtl")).unwrap();
        assert!(mtl.contains("map_Kd far.png\n"), "{mtl}");
        assert!(mtl.contains("map_Ks -bm 0.5 tex.png\n"), "{mtl}");
        assert!(mtl.contains("map_Bump tex.png\n"), "{mtl}");
        assert!(out.join("shared.mtl").is_file());

        // Written onto its own folder, or a folder holding one of its files: refused, nothing
        // touched.
        for bad in [
            scan.clone(),
            d.join("scans"),
            d.join("elsewhere"),
            d.to_path_buf(),
        ] {
            let e = write_moved_obj(&scan.join("a.obj"), &bad, moved()).unwrap_err();
            assert!(
                e.to_string().contains("contains") || e.to_string().contains(" is "),
                "{e}"
            );
        }
        for (p, bytes) in &before {
            assert_eq!(&std::fs::read(p).unwrap(), bytes, "{} changed", p.display());
        }
        // The scan, its two MTLs, and two textures (one named twice).
        assert_eq!(obj_inputs(&scan.join("a.obj")).unwrap().len(), 5);
    }

    /// Two different textures with the same file name in different places keep apart.
    #[test]
    fn two_sources_with_one_file_name_get_two_names() {
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path();
        let scan = d.join("scan");
        std::fs::create_dir_all(&scan).unwrap();
        std::fs::create_dir_all(d.join("b")).unwrap();
        std::fs::write(scan.join("t.png"), b"one").unwrap();
        std::fs::write(d.join("b/t.png"), b"two").unwrap();
        std::fs::write(
            scan.join("a.mtl"),
            "newmtl m\nmap_Kd t.png\nnewmtl n\nmap_Kd ../b/t.png\n",
        )
        .unwrap();
        std::fs::write(scan.join("a.obj"), "mtllib a.mtl\nv 0 0 0\n").unwrap();
        let out = d.join("out");
        write_moved_obj(&scan.join("a.obj"), &out, DMat4::IDENTITY).unwrap();
        assert_eq!(std::fs::read(out.join("t.png")).unwrap(), b"one");
        assert_eq!(std::fs::read(out.join("t_2.png")).unwrap(), b"two");
        let mtl = std::fs::read_to_string(out.join("a.mtl")).unwrap();
        assert!(
            mtl.contains("map_Kd t.png\n") && mtl.contains("map_Kd t_2.png\n"),
            "{mtl}"
        );
    }
}
