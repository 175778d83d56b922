//! The README's commands, run as a user in a fresh clone runs them (issue 50). The test reads
//! README.md itself, so the two cannot drift: every ```sh block's commands, in order, with
//! `synthgen` (and `cargo run --release -p synthgen-cli --`) meaning the binary cargo built for
//! the tests, in a temporary folder laid out as a clone with `../shared/data` beside it.
//!
//! What it understands of sh (the README keeps to it; anything else fails the test, naming
//! the line): one command per line, `\` continuations, `# comments`, `NAME=value` lines,
//! `$NAME` / `${NAME}` (split into words unquoted, one word in double quotes), '...' and "...".
//!
//! The rewrite to small sizes, and nothing else:
//! - `--frames N` renders at most [`FRAMES`] frames;
//! - `--epochs N` and `--detector-epochs N` train 1 epoch, and `train` / `detector train`
//!   without `--epochs` get `--epochs 1`;
//! - `../shared/data/lmo` holds the first [`LMO_PHOTOS`] of its 82 photographs (the README's
//!   `--refine views` takes ~15 minutes on all of them); the rest of `../shared/data` is the
//!   real one (linked).
//!
//! Commands it does not run are in [`NOT_RUN`], with the reason.

use std::collections::{BTreeSet, HashMap};
use std::path::Path;
use std::process::Command;
use std::time::Instant;

use serde_json::Value;

use crate::common::{copy_dir, repo_root, shared_data, stderr};

/// Frames a `--frames N` renders here at most.
const FRAMES: u64 = 4;

/// Photographs of LM-O's test scene kept in the test's `../shared/data/lmo`.
const LMO_PHOTOS: usize = 2;

/// Commands of the README this test does not run (a prefix of the command), and why.
const NOT_RUN: &[(&str, &str)] = &[
    (
        "cargo test",
        "the test suite itself: it would run this test again",
    ),
    (
        "cargo install",
        "installs into ~/.cargo/bin; the binary cargo built for the tests stands in for it",
    ),
    (
        "synthgen ros ",
        "a ROS 2 node: it runs until stopped and joins a DDS domain (UDP multicast); python/tests/test_ros_node.py runs it against Cyclone DDS in a private network namespace",
    ),
    (
        "pip install",
        "builds the Python wheel (maturin, minutes); python/tests/test_readme.py runs the README's Python example",
    ),
];

/// The repository's folders the README's commands read (copied into the temporary clone).
const REPO_DIRS: &[&str] = &["datasets", "scenes", "textures", "sensors"];

/// A command line of the README, as written and as run.
struct Line {
    text: String,
    words: Vec<String>,
}

/// The ```sh blocks of a markdown text, in order.
fn sh_blocks(md: &str) -> Vec<String> {
    let mut blocks = Vec::new();
    let mut block: Option<String> = None;
    for line in md.lines() {
        match &mut block {
            None if line.trim_end() == "```sh" => block = Some(String::new()),
            None => {}
            Some(_) if line.trim_end() == "```" => blocks.extend(block.take()),
            Some(b) => {
                b.push_str(line);
                b.push('\n');
            }
        }
    }
    assert!(block.is_none(), "README.md: an ```sh block is not closed");
    blocks
}

/// A block's logical lines: `\` continuations joined.
fn logical_lines(block: &str) -> Vec<String> {
    let mut out = Vec::new();
    let mut cur = String::new();
    for line in block.lines() {
        match line.strip_suffix('\\') {
            Some(head) => {
                cur.push_str(head);
                cur.push(' ');
            }
            None => {
                cur.push_str(line);
                out.push(std::mem::take(&mut cur));
            }
        }
    }
    assert!(cur.is_empty(), "README.md: a block ends in a continuation");
    out
}

/// `NAME` or `{NAME}` at the start of `rest` (after a `$`): the name and the characters read.
fn var_name(rest: &[char]) -> Result<(String, usize), String> {
    if rest.first() == Some(&'{') {
        let end = rest
            .iter()
            .position(|&c| c == '}')
            .ok_or("an unclosed ${")?;
        return Ok((rest[1..end].iter().collect(), end + 1));
    }
    let n = rest
        .iter()
        .take_while(|c| c.is_ascii_alphanumeric() || **c == '_')
        .count();
    if n == 0 {
        return Err("a $ without a variable name".into());
    }
    Ok((rest[..n].iter().collect(), n))
}

/// The words of one logical line, its variables expanded as sh expands them; `None` for a
/// blank or comment line.
fn words(line: &str, vars: &HashMap<String, String>) -> Result<Vec<String>, String> {
    let chars: Vec<char> = line.chars().collect();
    let lookup = |name: &str| {
        vars.get(name)
            .cloned()
            .ok_or_else(|| format!("${name} is not set by an earlier line of the block"))
    };
    let mut out = Vec::new();
    let mut cur = String::new();
    let mut in_word = false;
    let mut i = 0;
    while i < chars.len() {
        let c = chars[i];
        match c {
            ' ' | '\t' => {
                if in_word {
                    out.push(std::mem::take(&mut cur));
                    in_word = false;
                }
            }
            '#' if !in_word => break,
            '\'' => {
                let end = chars[i + 1..]
                    .iter()
                    .position(|&c| c == '\'')
                    .ok_or("an unclosed '")?;
                cur.extend(&chars[i + 1..i + 1 + end]);
                in_word = true;
                i += end + 1;
            }
            '"' => {
                in_word = true;
                i += 1;
                loop {
                    match chars.get(i) {
                        None => return Err("an unclosed \"".into()),
                        Some('"') => break,
                        Some('$') => {
                            let (name, n) = var_name(&chars[i + 1..])?;
                            cur.push_str(&lookup(&name)?);
                            i += n;
                        }
                        Some('\\' | '`') => return Err("\\ or ` inside \"...\"".into()),
                        Some(&c) => cur.push(c),
                    }
                    i += 1;
                }
            }
            '$' => {
                let (name, n) = var_name(&chars[i + 1..])?;
                let value = lookup(&name)?;
                for (k, piece) in value.split_whitespace().enumerate() {
                    if k > 0 {
                        out.push(std::mem::take(&mut cur));
                    }
                    cur.push_str(piece);
                    in_word = true;
                }
                i += n;
            }
            '|' | ';' | '&' | '<' | '>' | '`' | '(' | ')' | '*' | '?' | '[' | '{' | '}' | '~'
            | '\\' => return Err(format!("{c:?} (only plain commands are run)")),
            c => {
                cur.push(c);
                in_word = true;
            }
        }
        i += 1;
    }
    if in_word {
        out.push(cur);
    }
    Ok(out)
}

/// `NAME=value` (one word): the assignment.
fn assignment(words: &[String]) -> Option<(String, String)> {
    let (name, value) = words.first()?.split_once('=')?;
    let ok = !name.is_empty()
        && !name.starts_with(|c: char| c.is_ascii_digit())
        && name.chars().all(|c| c.is_ascii_alphanumeric() || c == '_');
    (ok && words.len() == 1).then(|| (name.to_string(), value.to_string()))
}

/// Every command line of the README's ```sh blocks, variables expanded (each block its own).
fn readme_commands(md: &str) -> Vec<Line> {
    let mut out = Vec::new();
    for block in sh_blocks(md) {
        let mut vars = HashMap::new();
        for text in logical_lines(&block) {
            let w = words(&text, &vars)
                .unwrap_or_else(|e| panic!("README.md: cannot run `{}`: {e}", text.trim()));
            if w.is_empty() {
                continue;
            }
            // `M=...` sets a variable; its value was expanded as one word, as sh does.
            if let Some((name, value)) = assignment(&w) {
                vars.insert(name, value);
                continue;
            }
            out.push(Line {
                text: text.split_whitespace().collect::<Vec<_>>().join(" "),
                words: w,
            });
        }
    }
    out
}

/// The synthgen arguments of a command (`synthgen ARGS`, `cargo run ... -p synthgen-cli --
/// ARGS`), else the reason it is not run; anything else fails the test.
fn synthgen_args(line: &Line) -> Result<Vec<String>, &'static str> {
    let w = &line.words;
    let joined = w.join(" ");
    for (prefix, why) in NOT_RUN {
        if joined.starts_with(prefix) {
            return Err(why);
        }
    }
    if w[0] == "synthgen" {
        return Ok(w[1..].to_vec());
    }
    if w.len() > 2 && w[0] == "cargo" && w[1] == "run" {
        let dash = w.iter().position(|a| a == "--");
        let pkg = w.windows(2).any(|p| p[0] == "-p" && p[1] == "synthgen-cli");
        if let (Some(dash), true) = (dash, pkg) {
            return Ok(w[dash + 1..].to_vec());
        }
    }
    panic!(
        "README.md runs `{}`, which this test cannot run: make it a synthgen command, or add it \
         to NOT_RUN in tests/cli/readme.rs with the reason",
        line.text
    )
}

/// The rewrite to small sizes (the module's doc lists it).
fn shrink(mut args: Vec<String>) -> Vec<String> {
    let mut i = 0;
    while i + 1 < args.len() {
        match args[i].as_str() {
            "--frames" => {
                let n: u64 = args[i + 1].parse().expect("--frames N");
                args[i + 1] = n.min(FRAMES).to_string();
            }
            "--epochs" | "--detector-epochs" => args[i + 1] = "1".to_string(),
            _ => {}
        }
        i += 1;
    }
    let trains = args.first().is_some_and(|a| a == "train")
        || (args.len() > 1 && args[0] == "detector" && args[1] == "train");
    if trains && !args.iter().any(|a| a == "--epochs") {
        args.extend(["--epochs".to_string(), "1".to_string()]);
    }
    args
}

/// `from` (a BOP dataset) with only the first `keep` images of each test scene: the JSON
/// files keyed by image id and the targets filtered, the models linked.
fn small_bop_copy(from: &Path, to: &Path, keep: usize) {
    std::fs::create_dir_all(to).unwrap();
    let read = |p: &Path| -> Value { serde_json::from_slice(&std::fs::read(p).unwrap()).unwrap() };
    let mut kept = BTreeSet::new();
    for scene in std::fs::read_dir(from.join("test")).unwrap() {
        let scene = scene.unwrap().path();
        let name = scene.file_name().unwrap().to_owned();
        let scene_id: u64 = name.to_str().unwrap().parse().unwrap();
        let dst = to.join("test").join(&name);
        std::fs::create_dir_all(&dst).unwrap();
        let gt = read(&scene.join("scene_gt.json"));
        let mut ids: Vec<u64> = gt
            .as_object()
            .unwrap()
            .keys()
            .map(|k| k.parse().unwrap())
            .collect();
        ids.sort_unstable();
        ids.truncate(keep);
        kept.extend(ids.iter().map(|&im| (scene_id, im)));
        for e in std::fs::read_dir(&scene).unwrap() {
            let e = e.unwrap();
            let (path, file) = (e.path(), e.file_name());
            if e.file_type().unwrap().is_dir() {
                // rgb/, depth/, mask/...: the images whose name starts with a kept id.
                std::fs::create_dir_all(dst.join(&file)).unwrap();
                for img in std::fs::read_dir(&path).unwrap() {
                    let img = img.unwrap();
                    let n = img.file_name();
                    let id: u64 = n.to_str().unwrap()[..6].parse().unwrap();
                    if ids.contains(&id) {
                        std::fs::copy(img.path(), dst.join(&file).join(&n)).unwrap();
                    }
                }
            } else {
                let mut v = read(&path);
                v.as_object_mut()
                    .unwrap()
                    .retain(|k, _| ids.contains(&k.parse().unwrap()));
                std::fs::write(dst.join(&file), v.to_string()).unwrap();
            }
        }
    }
    for e in std::fs::read_dir(from).unwrap() {
        let e = e.unwrap();
        let (path, file) = (e.path(), e.file_name());
        if file == "test" {
            continue;
        }
        if file == "test_targets_bop19.json" {
            let mut targets = read(&path);
            targets.as_array_mut().unwrap().retain(|t| {
                kept.contains(&(
                    t["scene_id"].as_u64().unwrap(),
                    t["im_id"].as_u64().unwrap(),
                ))
            });
            std::fs::write(to.join(&file), targets.to_string()).unwrap();
        } else {
            std::os::unix::fs::symlink(&path, to.join(&file)).unwrap();
        }
    }
}

#[test]
fn readme_sh_blocks_parse_as_the_test_runs_them() {
    let md = "```sh\nM=a/b   # models\nO=\"$M/x.ply $M/y.ply\"\nsynthgen render --objects $O \\\n    --frames 1500 --out 'o 1'\n```\n";
    let cmds = readme_commands(md);
    assert_eq!(cmds.len(), 1);
    assert_eq!(
        cmds[0].words,
        [
            "synthgen",
            "render",
            "--objects",
            "a/b/x.ply",
            "a/b/y.ply",
            "--frames",
            "1500",
            "--out",
            "o 1"
        ]
    );
    assert_eq!(
        shrink(cmds[0].words[1..].to_vec()),
        [
            "render",
            "--objects",
            "a/b/x.ply",
            "a/b/y.ply",
            "--frames",
            "4",
            "--out",
            "o 1"
        ]
    );
    assert_eq!(
        shrink(vec![
            "detector".into(),
            "train".into(),
            "--data".into(),
            "d".into()
        ]),
        ["detector", "train", "--data", "d", "--epochs", "1"]
    );
    // Not understood: refused with the reason, never run some other way.
    for bad in [
        "synthgen stats a | head",
        "O=$(ls)",
        "synthgen render --objects m/*.ply",
        "synthgen x $UNSET",
    ] {
        assert!(words(bad, &HashMap::new()).is_err(), "{bad}");
    }
}

#[test]
#[cfg_attr(
    not(has_shared_data),
    ignore = "needs ../shared/data beside the checkout (probed when the crate was built): the README's path renders the LM-O models and runs on the LM-O photographs"
)]
fn readme_commands_run_as_written() {
    let root = repo_root();
    let md = std::fs::read_to_string(root.join("README.md")).unwrap();
    let lines = readme_commands(&md);

    // The setup the README promises: two commands, the render and the tests.
    let setup = md
        .split("\n## ")
        .find(|s| s.starts_with("Setup: two commands"))
        .expect("README.md has a \"Setup: two commands\" section");
    let setup: Vec<String> = readme_commands(setup).into_iter().map(|l| l.text).collect();
    assert_eq!(setup.len(), 2, "{setup:?}");
    assert!(
        setup[0].starts_with("cargo run --release -p synthgen-cli -- render "),
        "{setup:?}"
    );
    assert_eq!(setup[1], "cargo test --workspace");

    // A clone: the repository's data folders, with ../shared/data beside it.
    let tmp = tempfile::tempdir().unwrap();
    let clone = tmp.path().join("synthgen");
    for d in REPO_DIRS {
        copy_dir(&root.join(d), &clone.join(d), &[]);
    }
    let shared = tmp.path().join("shared/data");
    std::fs::create_dir_all(&shared).unwrap();
    for e in std::fs::read_dir(shared_data()).unwrap() {
        let e = e.unwrap();
        if e.file_name() == "lmo" {
            small_bop_copy(&e.path(), &shared.join("lmo"), LMO_PHOTOS);
        } else {
            std::os::unix::fs::symlink(e.path(), shared.join(e.file_name())).unwrap();
        }
    }

    let started = Instant::now();
    let mut ran = 0;
    for line in &lines {
        let args = match synthgen_args(line) {
            Ok(args) => shrink(args),
            Err(why) => {
                eprintln!("not run: {} ({why})", line.text);
                continue;
            }
        };
        let t = Instant::now();
        let o = Command::new(env!("CARGO_BIN_EXE_synthgen"))
            .args(&args)
            .current_dir(&clone)
            .env_remove("RUST_LOG")
            .output()
            .unwrap();
        eprintln!(
            "{:6.1} s  synthgen {}",
            t.elapsed().as_secs_f64(),
            args.join(" ")
        );
        assert!(
            o.status.success(),
            "README.md's `{}` failed (run as `synthgen {}`):\n{}\n{}",
            line.text,
            args.join(" "),
            String::from_utf8_lossy(&o.stdout),
            stderr(&o)
        );
        ran += 1;
    }
    eprintln!(
        "{ran} of {} README commands run in {:.1} s",
        lines.len(),
        started.elapsed().as_secs_f64()
    );
    assert!(ran >= 10, "only {ran} commands ran: {}", lines.len());
}
