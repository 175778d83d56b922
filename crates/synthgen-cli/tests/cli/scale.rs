//! Shards, merge and resume: the outputs must be byte-identical to one uninterrupted run.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::Duration;

use crate::common::{run, stderr, synthgen, tree};
use crate::render::write_box_ply;

fn manifest(root: &Path) -> serde_json::Value {
    serde_json::from_slice(&std::fs::read(root.join("synthgen.json")).unwrap()).unwrap()
}

/// Asserts two datasets hold the same files with the same bytes, apart from synthgen.json.
fn assert_same_files(a: &Path, b: &Path) {
    let (mut x, mut y) = (tree(a), tree(b));
    x.remove(Path::new("synthgen.json"));
    y.remove(Path::new("synthgen.json"));
    let only = |p: &BTreeMap<PathBuf, Vec<u8>>, q: &BTreeMap<PathBuf, Vec<u8>>| {
        p.keys()
            .filter(|k| !q.contains_key(*k))
            .cloned()
            .collect::<Vec<_>>()
    };
    let (only_a, only_b) = (only(&x, &y), only(&y, &x));
    assert!(
        only_a.is_empty() && only_b.is_empty(),
        "file lists differ: only in {}: {only_a:?}; only in {}: {only_b:?}",
        a.display(),
        b.display()
    );
    for (rel, bytes) in &x {
        assert!(y[rel] == *bytes, "{} differs", rel.display());
    }
    assert!(x.len() > 20, "too few files: {}", x.len());
}

/// `synthgen render` of two boxes; `extra` may override --frames, --seed, --image-size.
fn render_cmd(mesh: &Path, out: &Path, extra: &[&str]) -> Command {
    let mut args: Vec<&str> = vec!["--chunk-size", "4"];
    for (flag, default) in [
        ("--frames", "11"),
        ("--seed", "5"),
        ("--image-size", "96,72"),
    ] {
        if !extra.contains(&flag) {
            args.extend([flag, default]);
        }
    }
    let mut c = synthgen();
    c.args(["render", "-q", "--objects"])
        .arg(mesh)
        .arg(mesh)
        .args(args)
        .arg("--out")
        .arg(out)
        .args(extra);
    c
}

#[test]
fn shards_merged_equal_one_process_byte_for_byte() {
    let dir = tempfile::tempdir().unwrap();
    let mesh = dir.path().join("box.ply");
    write_box_ply(&mesh);
    let single = dir.path().join("single");
    assert!(run(&mut render_cmd(&mesh, &single, &[])).status.success());
    // 3 shards of 11 frames in chunks of 4: scene folders 0 and 1 are split between shards.
    let shards: Vec<PathBuf> = (0..3).map(|i| dir.path().join(format!("s{i}"))).collect();
    for (i, s) in shards.iter().enumerate() {
        let shard = format!("{i}/3");
        let o = run(&mut render_cmd(
            &mesh,
            s,
            &["--shard", &shard, "--jobs", "2"],
        ));
        assert!(o.status.success());
    }
    // Shard 1 of 3 holds frames 3..7 only.
    let m1 = manifest(&shards[1]);
    assert_eq!(m1["frames"], 4);
    assert_eq!(m1["extra"]["frame_range"], serde_json::json!([3, 7]));
    let merged = dir.path().join("merged");
    // Shards in any order.
    let o = run(synthgen()
        .args(["merge", "-q"])
        .args([&shards[2], &shards[0], &shards[1]])
        .arg("--out")
        .arg(&merged));
    assert!(o.status.success());
    assert_same_files(&single, &merged);
    // The manifest says what one process would, plus where the shards came from.
    let mut m = manifest(&merged);
    let from = m["extra"]
        .as_object_mut()
        .unwrap()
        .remove("merged_from")
        .unwrap();
    assert_eq!(from.as_array().unwrap().len(), 3);
    let mut s = manifest(&single);
    m.as_object_mut().unwrap().remove("command_line");
    s.as_object_mut().unwrap().remove("command_line");
    assert_eq!(m, s);
}

#[test]
fn merge_refuses_missing_mismatched_and_unfinished_shards() {
    let dir = tempfile::tempdir().unwrap();
    let mesh = dir.path().join("box.ply");
    write_box_ply(&mesh);
    let a = dir.path().join("a");
    let b = dir.path().join("b");
    let c = dir.path().join("c");
    assert!(run(&mut render_cmd(&mesh, &a, &["--shard", "0/2"]))
        .status
        .success());
    assert!(run(&mut render_cmd(
        &mesh,
        &b,
        &["--shard", "1/2", "--seed", "6"]
    ))
    .status
    .success());
    let o = run(synthgen()
        .args(["merge"])
        .arg(&a)
        .arg("--out")
        .arg(dir.path().join("o")));
    assert_eq!(o.status.code(), Some(1));
    assert!(stderr(&o).contains("missing shards: 1/2"), "{}", stderr(&o));
    let o = run(synthgen()
        .arg("merge")
        .args([&a, &b])
        .arg("--out")
        .arg(dir.path().join("o")));
    assert_eq!(o.status.code(), Some(1));
    assert!(
        stderr(&o).contains("not shards of the same run"),
        "{}",
        stderr(&o)
    );
    assert!(run(&mut render_cmd(&mesh, &c, &["--shard", "1/2"]))
        .status
        .success());
    std::fs::write(c.join(".synthgen-run.json"), "{}").unwrap();
    let o = run(synthgen()
        .arg("merge")
        .args([&a, &c])
        .arg("--out")
        .arg(dir.path().join("o")));
    assert_eq!(o.status.code(), Some(1));
    assert!(stderr(&o).contains("shard is unfinished"), "{}", stderr(&o));
}

/// splitmix64: reproducible kill points without a rand dependency.
fn next(state: &mut u64) -> u64 {
    *state = state.wrapping_add(0x9e37_79b9_7f4a_7c15);
    let mut z = *state;
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^ (z >> 31)
}

#[test]
fn killed_at_random_points_then_resumed_is_byte_identical() {
    let dir = tempfile::tempdir().unwrap();
    let mesh = dir.path().join("box.ply");
    write_box_ply(&mesh);
    let reference = dir.path().join("reference");
    let frames = ["--frames", "60", "--image-size", "320,240", "--jobs", "1"];
    let t0 = std::time::Instant::now();
    assert!(run(&mut render_cmd(&mesh, &reference, &frames))
        .status
        .success());
    let full_ms = t0.elapsed().as_millis().max(20) as u64;

    let out = dir.path().join("killed");
    let mut rng = 0x5eed_u64;
    let mut kills = 0;
    for attempt in 0..8 {
        let mut cmd = render_cmd(&mesh, &out, &frames);
        if attempt > 0 {
            cmd.arg("--resume");
        }
        let mut child = cmd
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .unwrap();
        // Short random slices of a full run, so that most attempts die part-way (start-up,
        // mid-frame, mid-JSON) and each one gets a little further.
        let delay = 2 + next(&mut rng) % (full_ms / 5);
        std::thread::sleep(Duration::from_millis(delay));
        if child.try_wait().unwrap().is_none() {
            child.kill().unwrap(); // SIGKILL
            kills += 1;
        }
        child.wait().unwrap();
    }
    eprintln!("killed {kills} of 8 runs (a full run takes {full_ms} ms)");
    assert!(kills >= 2, "only {kills} kills landed");
    let o = run(render_cmd(&mesh, &out, &frames).arg("--resume"));
    assert!(o.status.success(), "{}", stderr(&o));
    assert_same_files(&reference, &out);
    // With --resume left out of the recorded command line, the manifest matches too.
    let (mut a, mut b) = (manifest(&reference), manifest(&out));
    a["command_line"] = serde_json::Value::Null;
    b["command_line"] = serde_json::Value::Null;
    assert_eq!(a, b);
}

#[test]
fn resume_refuses_a_different_run_and_finishes_a_finished_one() {
    let dir = tempfile::tempdir().unwrap();
    let mesh = dir.path().join("box.ply");
    write_box_ply(&mesh);
    let out = dir.path().join("o");
    assert!(run(&mut render_cmd(&mesh, &out, &[])).status.success());
    let before = tree(&out);
    let o = run(render_cmd(&mesh, &out, &["--seed", "9"]).arg("--resume"));
    assert_eq!(o.status.code(), Some(1));
    assert!(stderr(&o).contains("seed differs"), "{}", stderr(&o));
    let o = run(render_cmd(&mesh, &out, &[]).arg("--resume"));
    assert!(o.status.success());
    assert!(tree(&out) == before, "resuming a finished run changed it");
}

/// A tmpfs mounted at `dir`. The tests that mount one are ignored where the build script
/// could not mount a tmpfs (it needs root and a sandbox that allows it).
struct Mount(PathBuf);

impl Mount {
    fn tmpfs(dir: &Path, opts: &str) -> Mount {
        std::fs::create_dir_all(dir).unwrap();
        let o = Command::new("mount")
            .args(["-t", "tmpfs", "-o", opts, "tmpfs"])
            .arg(dir)
            .output()
            .unwrap();
        assert!(
            o.status.success(),
            "cannot mount a tmpfs (the build script could, or SYNTHGEN_REQUIRE_TMPFS=1): {}",
            String::from_utf8_lossy(&o.stderr)
        );
        Mount(dir.to_path_buf())
    }
}

impl Drop for Mount {
    fn drop(&mut self) {
        let _ = Command::new("umount").arg(&self.0).status();
    }
}

#[test]
#[cfg_attr(
    not(has_tmpfs),
    ignore = "needs to mount a tmpfs: root (probed when the crate was built)"
)]
fn full_disk_fails_clearly_and_what_was_written_resumes() {
    let dir = tempfile::tempdir().unwrap();
    let mesh = dir.path().join("box.ply");
    write_box_ply(&mesh);
    let mnt = Mount::tmpfs(&dir.path().join("mnt"), "size=256k");
    let args = ["--frames", "300", "--image-size", "64,48", "--jobs", "1"];
    let full = mnt.0.join("o");
    let o = run(&mut render_cmd(&mesh, &full, &args));
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    let err = stderr(&o);
    assert!(err.contains("no space left on device"), "{err}");
    assert!(err.contains(&full.display().to_string()), "{err}");
    // Move what was written to a disk with room and finish it.
    let moved = dir.path().join("moved");
    let cp = Command::new("cp")
        .arg("-a")
        .arg(&full)
        .arg(&moved)
        .status()
        .unwrap();
    assert!(cp.success());
    drop(mnt);
    assert!(!moved.join("synthgen.json").exists());
    let o = run(render_cmd(&mesh, &moved, &args).arg("--resume"));
    assert!(o.status.success(), "{}", stderr(&o));
    let reference = dir.path().join("reference");
    assert!(run(&mut render_cmd(&mesh, &reference, &args))
        .status
        .success());
    assert_same_files(&reference, &moved);
}

#[test]
#[cfg_attr(
    not(has_tmpfs),
    ignore = "needs to mount a tmpfs: root (probed when the crate was built)"
)]
fn read_only_output_fails_clearly() {
    let dir = tempfile::tempdir().unwrap();
    let mesh = dir.path().join("box.ply");
    write_box_ply(&mesh);
    let mnt = Mount::tmpfs(&dir.path().join("ro"), "ro,size=64k");
    let out = mnt.0.join("o");
    let o = run(&mut render_cmd(&mesh, &out, &[]));
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    let err = stderr(&o);
    assert!(err.contains("Read-only file system"), "{err}");
    assert!(err.contains(&out.display().to_string()), "{err}");
}

/// Regression (issue 50): an interrupted `render --replay` left a folder neither a re-run nor
/// `--force` would take, and `--replay` could not `--resume`. Killed at random points and
/// resumed, a replay ends byte for byte as one uninterrupted run; a killed one is replaced by
/// `--force`; `--resume` of another replay is refused.
#[test]
fn a_replay_killed_at_random_points_resumes_byte_identical_or_is_forced() {
    let dir = tempfile::tempdir().unwrap();
    let mesh = dir.path().join("box.ply");
    write_box_ply(&mesh);
    let source = dir.path().join("source");
    let o = run(&mut render_cmd(
        &mesh,
        &source,
        &["--frames", "120", "--image-size", "320,240"],
    ));
    assert!(o.status.success(), "{}", stderr(&o));
    let replay = |out: &Path, extra: &[&str]| {
        let mut c = synthgen();
        c.args(["render", "-q", "--jobs", "1", "--replay"])
            .arg(&source)
            .arg("--out")
            .arg(out)
            .args(extra);
        c
    };
    let reference = dir.path().join("reference");
    let t0 = std::time::Instant::now();
    assert!(run(&mut replay(&reference, &[])).status.success());
    let full_ms = t0.elapsed().as_millis().max(20) as u64;

    let out = dir.path().join("killed");
    let mut rng = 0x7e91_u64;
    let mut kills = 0;
    for attempt in 0..8 {
        let mut cmd = replay(&out, if attempt > 0 { &["--resume"] } else { &[] });
        let mut child = cmd
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .unwrap();
        let delay = 2 + next(&mut rng) % (full_ms / 4);
        std::thread::sleep(Duration::from_millis(delay));
        if child.try_wait().unwrap().is_none() {
            child.kill().unwrap();
            kills += 1;
        }
        child.wait().unwrap();
    }
    eprintln!("killed {kills} of 8 replays (a full one takes {full_ms} ms)");
    assert!(kills >= 2, "only {kills} kills landed");
    // Another seed is another replay.
    if !out.join("synthgen.json").exists() {
        let o = run(&mut replay(&out, &["--resume", "--seed", "3"]));
        assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
        assert!(stderr(&o).contains("holds another run"), "{}", stderr(&o));
    }
    let o = run(&mut replay(&out, &["--resume"]));
    assert!(o.status.success(), "{}", stderr(&o));
    assert_same_files(&reference, &out);

    // Killed early, then replaced with --force: the run plan says the folder is a replay's.
    let forced = dir.path().join("forced");
    let mut child = replay(&forced, &[])
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    std::thread::sleep(Duration::from_millis(full_ms / 3));
    let _ = child.kill();
    child.wait().unwrap();
    let o = run(&mut replay(&forced, &["--force"]));
    assert!(o.status.success(), "{}", stderr(&o));
    assert_same_files(&reference, &forced);
}
