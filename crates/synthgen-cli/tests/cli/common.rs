use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

pub fn synthgen() -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_synthgen"));
    c.env_remove("RUST_LOG");
    c
}

/// Runs the binary and returns its output, printing stderr for debugging failures.
pub fn run(cmd: &mut Command) -> Output {
    let out = cmd.output().expect("synthgen runs");
    eprintln!(
        "--- synthgen stderr ---\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    out
}

pub fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// `../shared/data` beside the checkout. The tests that use it are ignored where the build
/// script found none (`cfg(has_shared_data)`, synthgen-probe), so here it must exist.
pub fn shared_data() -> PathBuf {
    let p = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../../shared/data");
    p.canonicalize().unwrap_or_else(|e| {
        panic!(
            "shared data at {}: {e} (it was there when the tests were built, or SYNTHGEN_REQUIRE_SHARED=1)",
            p.display()
        )
    })
}

/// `../shared/data/ycbv_real` (the real YCB-Video frames).
pub fn ycbv_real() -> PathBuf {
    shared_data().join("ycbv_real")
}

/// A successful run's stdout, parsed as JSON.
pub fn stdout_json(o: &Output) -> serde_json::Value {
    assert!(o.status.success(), "{}", stderr(o));
    serde_json::from_slice(&o.stdout).expect("JSON on stdout")
}

/// A run refused as a user error (exit 1) whose stderr names every one of `words`.
pub fn refused(o: &Output, words: &[&str]) {
    let e = stderr(o);
    assert_eq!(o.status.code(), Some(1), "{e}");
    for w in words {
        assert!(e.contains(w), "{w:?} not in: {e}");
    }
}

/// The repository root.
pub fn repo_root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../..")
        .canonicalize()
        .expect("repo root")
}

/// A small copy of the real dataset to break: scene 0000 (frames 1-2) with its models.
pub fn ycbv_small_copy(real: &Path, to: &Path) {
    std::fs::create_dir_all(to.join("data/0000")).unwrap();
    std::fs::copy(real.join("classes.txt"), to.join("classes.txt")).unwrap();
    for f in 1..=2 {
        for s in ["color.png", "depth.png", "label.png", "meta.mat", "box.txt"] {
            let name = format!("{f:06}-{s}");
            std::fs::copy(
                real.join("data/0000").join(&name),
                to.join("data/0000").join(&name),
            )
            .unwrap();
        }
    }
    for class in ["009_gelatin_box", "025_mug", "061_foam_brick"] {
        let dir = to.join("models").join(class);
        std::fs::create_dir_all(&dir).unwrap();
        for f in [
            "textured_simple.obj",
            "textured_simple.obj.mtl",
            "points.xyz",
        ] {
            std::fs::copy(real.join("models").join(class).join(f), dir.join(f)).unwrap();
        }
    }
}

/// Copies `from` to `to` (files, recursively), leaving out the top-level entries `skip`.
pub fn copy_dir(from: &Path, to: &Path, skip: &[&str]) {
    std::fs::create_dir_all(to).unwrap();
    for e in std::fs::read_dir(from).unwrap() {
        let e = e.unwrap();
        let name = e.file_name();
        if skip.iter().any(|s| name == *s) {
            continue;
        }
        let dst = to.join(&name);
        if e.file_type().unwrap().is_dir() {
            copy_dir(&e.path(), &dst, &[]);
        } else {
            std::fs::copy(e.path(), dst).unwrap();
        }
    }
}

/// Every file under `root` (hidden ones included), relative path → bytes.
pub fn tree(root: &Path) -> BTreeMap<PathBuf, Vec<u8>> {
    let mut out = BTreeMap::new();
    let mut stack = vec![root.to_path_buf()];
    while let Some(dir) = stack.pop() {
        for e in std::fs::read_dir(&dir).unwrap() {
            let p = e.unwrap().path();
            if p.is_dir() {
                stack.push(p);
            } else {
                out.insert(
                    p.strip_prefix(root).unwrap().to_path_buf(),
                    std::fs::read(&p).unwrap(),
                );
            }
        }
    }
    out
}
