//! Data on stdout: a reader that went away (`synthgen stats D | head`) ends the output quietly
//! (exit status as without it, files still written); a full device behind stdout is an error
//! that names it (exit 1). Both used to panic with exit 101 (issue 26).

use std::process::{Command, Stdio};

use crate::common::{stderr, synthgen, ycbv_real};
use crate::mix::render_tiny;

/// A pipe whose reader is gone before the first byte: every write gets EPIPE.
fn closed_pipe() -> Stdio {
    let (reader, writer) = std::io::pipe().unwrap();
    drop(reader);
    writer.into()
}

fn dev_full() -> Stdio {
    std::fs::OpenOptions::new()
        .write(true)
        .open("/dev/full")
        .unwrap()
        .into()
}

/// Runs `cmd` with stdout closed, then (when it prints data) with stdout on /dev/full, and
/// checks both outcomes.
fn check(cmd: impl Fn() -> Command, what: &str, ok_status: i32) {
    let printed = !cmd().output().unwrap().stdout.is_empty();
    let o = cmd().stdout(closed_pipe()).output().unwrap();
    let e = stderr(&o);
    assert_eq!(
        o.status.code(),
        Some(ok_status),
        "{what}, stdout closed: {e}"
    );
    assert!(!e.contains("panicked"), "{what}: {e}");
    if !printed {
        return;
    }
    let o = cmd().stdout(dev_full()).output().unwrap();
    let e = stderr(&o);
    assert_eq!(o.status.code(), Some(1), "{what}, stdout full: {e}");
    assert!(
        e.contains("cannot write to standard output") && e.contains("No space left"),
        "{what}: {e}"
    );
    assert!(!e.contains("panicked"), "{what}: {e}");
}

#[test]
fn commands_that_print_data_end_quietly_on_a_closed_pipe_and_fail_on_a_full_device() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path().to_path_buf();
    render_tiny(&d, "a", 4, 1);
    std::fs::write(
        d.join("r.csv"),
        crate::train::gt_as_results(&d.join("a"), 0.0),
    )
    .unwrap();
    // (`validate a` prints nothing on stdout when there is no problem.)
    let cmds: [(&[&str], i32); 8] = [
        (&["stats", "a"], 0),
        (&["stats", "a", "--json"], 0),
        (&["stats", "a", "a"], 0),
        (&["validate", "a"], 0),
        (&["validate", "a", "--json"], 0),
        (
            &[
                "eval",
                "--results",
                "r.csv",
                "--data",
                "a",
                "--json",
                "s.json",
            ],
            0,
        ),
        (&["eval", "--bop", "--results", "r.csv", "--data", "a"], 0),
        (&["annotate", "a", "--compare"], 0),
    ];
    for (args, status) in cmds {
        let _ = std::fs::remove_file(d.join("s.json"));
        check(
            || {
                let mut c = synthgen();
                c.current_dir(&d).args(args);
                c
            },
            &args.join(" "),
            status,
        );
    }
    // A file the command writes besides stdout is written although stdout was closed.
    let o = synthgen()
        .current_dir(&d)
        .args([
            "eval",
            "--results",
            "r.csv",
            "--data",
            "a",
            "--json",
            "s.json",
        ])
        .stdout(closed_pipe())
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(d.join("s.json").is_file());
    // A dataset with problems keeps its exit status 1 when its reader went away.
    std::fs::remove_file(d.join("a/train_pbr/000000/depth/000001.png")).unwrap();
    let o = synthgen()
        .current_dir(&d)
        .args(["validate", "a"])
        .stdout(closed_pipe())
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
}

#[test]
#[cfg_attr(
    not(has_shared_data),
    ignore = "needs ../shared/data beside the checkout (probed when the crate was built)"
)]
fn fits_print_their_reports_quietly_into_a_closed_pipe() {
    let real = ycbv_real();
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path().to_path_buf();
    for (args, name) in [
        (vec!["sensor", "fit", "--scenes", "1", "--out"], "s.toml"),
        (vec!["scene", "fit", "--scenes", "1", "--out"], "scene.toml"),
    ] {
        let cmd = || {
            let mut c = synthgen();
            c.current_dir(&d)
                .args(&args[..2])
                .arg("--data")
                .arg(&real)
                .args(&args[2..])
                .arg(name)
                .arg("--force");
            c
        };
        check(cmd, &args.join(" "), 0);
        assert!(d.join(name).is_file(), "{name}");
    }
}
