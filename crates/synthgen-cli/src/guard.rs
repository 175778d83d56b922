//! The one rule every command shares, checked before any command runs: an output (a folder or
//! a file) is never one of the command's inputs, never lies inside one and never contains one
//! (which `--force` would wipe), and no two outputs are the same path.
//!
//! [`paths`] lists each command's inputs and outputs from its flags; its `match` names every
//! command, so a new one cannot be added without saying what it reads and writes. The
//! libraries keep their own checks for what only they know (the files a scan's MTL names, the
//! paths a scene file or a results folder holds); this is the part the command line decides.
//! `annotate` and `export coco` write into their dataset by design (BOP's masks,
//! `scene_gt_info.json`, `scene_gt_coco.json`); their other outputs follow the rule, and
//! `export coco --out` may replace only an earlier COCO file.

use std::path::{Path, PathBuf};

use anyhow::Result;
use synthgen_core::paths::{overlap, resolve};

use crate::cli::{
    Command, DetectorCommand, ExperimentCommand, ExportCommand, ModelCommand, PathOrCount,
    SceneCommand, SensorCommand,
};

/// What a command reads and writes, by role ("dataset", "--plot").
#[derive(Debug, Default)]
pub struct CommandPaths {
    pub inputs: Vec<(&'static str, PathBuf)>,
    pub outputs: Vec<(&'static str, PathBuf)>,
}

impl CommandPaths {
    fn input(&mut self, role: &'static str, p: &Path) {
        self.inputs.push((role, p.to_path_buf()));
    }

    fn input_opt(&mut self, role: &'static str, p: &Option<PathBuf>) {
        if let Some(p) = p {
            self.input(role, p);
        }
    }

    /// A flag that names a file or a built-in (`--sensor d455`, `--camera linemod`): an
    /// input only when it is a file.
    fn input_if_file(&mut self, role: &'static str, s: &Option<String>) {
        if let Some(s) = s.as_deref().map(Path::new).filter(|p| p.is_file()) {
            self.input(role, s);
        }
    }

    fn output(&mut self, role: &'static str, p: &Path) {
        self.outputs.push((role, p.to_path_buf()));
    }

    fn output_opt(&mut self, role: &'static str, p: &Option<PathBuf>) {
        if let Some(p) = p {
            self.output(role, p);
        }
    }

    /// A checkpoint file and the run folder it sits in (config.json beside it).
    fn checkpoint(&mut self, p: &Path) {
        self.input("checkpoint", p);
        if p.is_file() {
            if let Some(dir) = p.parent().filter(|d| !d.as_os_str().is_empty()) {
                self.input("checkpoint's run folder", dir);
            }
        }
    }

    /// A flag that names a run folder (an input as `role`) or its checkpoint file.
    fn run_or_checkpoint(&mut self, role: &'static str, p: &Path) {
        if p.is_dir() {
            self.input(role, p);
        } else {
            self.checkpoint(p);
        }
    }
}

/// The inputs and outputs `command` names on its command line.
pub fn paths(command: &Command) -> CommandPaths {
    let mut p = CommandPaths::default();
    match command {
        Command::Render(a) => {
            for o in &a.objects {
                p.input("object mesh", o);
            }
            p.input_opt("--scene", &a.scene);
            p.input_if_file("--sensor", &a.sensor);
            p.input_if_file("--camera", &a.camera);
            p.input_opt("--replay dataset", &a.replay);
            p.input_opt("--replay-models", &a.replay_models);
            p.input_opt("--background-dir", &a.background_dir);
            p.input_opt("--blender-venv", &a.blender_venv);
            p.output("--out", &a.out);
        }
        Command::Mix(a) => {
            for (role, x) in [("real dataset", &a.real), ("synthetic dataset", &a.synth)] {
                if let PathOrCount::Path(d) = x {
                    p.input(role, d);
                }
            }
            p.output_opt("--out", &a.out);
        }
        Command::Stats(a) => {
            for d in &a.dirs {
                p.input("dataset", d);
            }
            p.output_opt("--plot", &a.plot);
        }
        Command::Preview(a) => {
            p.input("dataset", &a.dir);
            p.output("--out", &a.out);
        }
        Command::View(a) => {
            for d in &a.dirs {
                p.input("dataset", d);
            }
            p.input_opt("--results", &a.results);
        }
        Command::Annotate(a) => {
            // The masks and scene_gt_info go into the dataset itself, by design.
            p.input("dataset", &a.dir);
            p.output_opt("--report", &a.report);
            p.output_opt("--overlay", &a.overlay);
        }
        Command::Export(ExportCommand::Coco(a)) => {
            // Into the dataset by design; `--out` is checked by [`check_coco_out`].
            p.input("dataset", &a.dir);
        }
        Command::Convert(a) => {
            p.input("input dataset", &a.input);
            p.input_opt("--classes", &a.classes);
            p.output("output folder", &a.output);
        }
        Command::Validate(a) => p.input("dataset", &a.dir),
        Command::Train(a) => {
            p.input("dataset", &a.data);
            for i in &a.init {
                p.input("--init checkpoint", i);
            }
            p.output("--out", &a.out);
        }
        Command::Eval(a) => {
            p.input("dataset", &a.data);
            p.input_opt("--results", &a.results);
            if let Some(c) = &a.checkpoint {
                p.checkpoint(c);
            }
            p.input_opt("--refine-models", &a.refine_models);
            p.input_opt("--detections", &a.detections);
            if let Some(d) = &a.detector {
                p.run_or_checkpoint("--detector", d);
            }
            p.input_opt("--targets", &a.targets);
            p.output_opt("--json", &a.json);
            p.output_opt("--save-results", &a.save_results);
            p.output_opt("--bop-errors", &a.bop_errors);
        }
        Command::Merge(a) => {
            for d in &a.dirs {
                p.input("shard", d);
            }
            p.output("--out", &a.out);
        }
        Command::Detector(DetectorCommand::Train(a)) => {
            p.input_opt("dataset", &a.data);
            p.output("--out", &a.out);
        }
        Command::Detector(DetectorCommand::Run(a)) => {
            p.run_or_checkpoint("detector", &a.checkpoint);
            p.input("dataset", &a.data);
            p.output("--out", &a.out);
        }
        Command::Detector(DetectorCommand::Eval(a)) => {
            p.input("--detections", &a.detections);
            p.input("dataset", &a.data);
            p.input_opt("--targets", &a.targets);
            p.output_opt("--out", &a.out);
            p.output_opt("--gt-out", &a.gt_out);
            p.output_opt("--draw", &a.draw);
        }
        Command::Predict(a) => {
            p.run_or_checkpoint("--model", &a.model);
            p.run_or_checkpoint("--detector", &a.detector);
            p.input_opt("--images", &a.images);
            p.input_opt("--camera", &a.camera);
            p.input_opt("--depth", &a.depth);
            p.input_opt("--data", &a.data);
            p.input_opt("--bag", &a.bag);
            p.input_opt("--refine-models", &a.refine.refine_models);
            p.output("--out", &a.out);
            p.output_opt("--draw", &a.draw);
        }
        Command::Ros(a) => {
            p.run_or_checkpoint("--model", &a.model);
            p.run_or_checkpoint("--detector", &a.detector);
            p.input_opt("--refine-models", &a.refine.refine_models);
            p.output_opt("--record", &a.record);
        }
        Command::Experiment(ExperimentCommand::Mix(a)) => {
            p.input_opt("--real", &a.real);
            p.input_opt("--synth", &a.synth);
            p.input_opt("--scene", &a.scene);
            for o in &a.objects {
                p.input("object mesh", o);
            }
            p.output("--out", &a.out);
        }
        Command::Experiment(ExperimentCommand::Sim2real(a)) => {
            p.input_opt("--fit", &a.fit);
            p.input("--test", &a.test);
            p.input_opt("--scene", &a.scene);
            p.input_opt("--models", &a.models);
            p.output("--out", &a.out);
        }
        Command::Experiment(ExperimentCommand::Rgb(a)) => {
            p.input("--train", &a.train);
            p.input("--test", &a.test);
            p.output("--out", &a.out);
        }
        Command::Sensor(SensorCommand::Fit(a)) => {
            p.input("dataset", &a.data);
            p.input_opt("--base", &a.base);
            p.output("--out", &a.out);
            p.output_opt("--plot", &a.plot);
        }
        Command::Sensor(SensorCommand::Compare(a)) => {
            p.input("--real", &a.real);
            p.input("--synth", &a.synth);
            p.output_opt("--plot", &a.plot);
        }
        Command::Sensor(SensorCommand::CompareRgb(a)) => {
            p.input("--real", &a.real);
            p.input("--synth", &a.synth);
        }
        Command::Model(ModelCommand::Align(a)) => {
            p.input_opt("--scan", &a.scan);
            p.input_opt("--to", &a.to);
            p.input_opt("--scans", &a.scans);
            p.input_opt("--to-dataset", &a.to_dataset);
            p.output("--out", &a.out);
        }
        Command::Scene(SceneCommand::Fit(a)) => {
            p.input("dataset", &a.data);
            p.input_opt("--sensor", &a.sensor);
            p.output("--out", &a.out);
        }
    }
    p
}

/// Refuses `command` when one of its outputs is, lies inside or contains one of its inputs,
/// or two of its outputs are the same path.
pub fn check(command: &Command) -> Result<()> {
    let p = paths(command);
    for (role, out) in &p.outputs {
        for (in_role, input) in &p.inputs {
            if let Some(o) = overlap(out, input) {
                return Err(crate::commands::user_error(
                    format!(
                        "the output {} ({role}) {} the {in_role} {}: a command never writes into its inputs",
                        out.display(),
                        o.verb(),
                        input.display()
                    ),
                    format!("choose another {role}, outside every input"),
                ));
            }
        }
    }
    for (i, (role_a, a)) in p.outputs.iter().enumerate() {
        for (role_b, b) in &p.outputs[i + 1..] {
            if resolve(a) == resolve(b) {
                return Err(crate::commands::user_error(
                    format!("{role_a} and {role_b} are the same path {}", a.display()),
                    "give each output its own path",
                ));
            }
        }
    }
    if let Command::Export(ExportCommand::Coco(a)) = command {
        if let Some(out) = &a.out {
            check_coco_out(out)?;
        }
    }
    Ok(())
}

/// `export coco --out FILE` writes into its dataset by design, but may replace only a COCO
/// file (an earlier export), never a file the dataset is made of.
fn check_coco_out(out: &Path) -> Result<()> {
    if out.is_dir() {
        return Err(crate::commands::user_error(
            format!("--out {} is a folder", out.display()),
            "give a file name, e.g. --out data/mix/test_coco.json",
        ));
    }
    if !out.exists() {
        return Ok(());
    }
    let is_coco = std::fs::read(out)
        .ok()
        .and_then(|b| serde_json::from_slice::<serde_json::Value>(&b).ok())
        .is_some_and(|v| v.get("annotations").is_some() && v.get("images").is_some());
    if is_coco {
        return Ok(());
    }
    Err(crate::commands::user_error(
        format!(
            "--out {} exists and is not a COCO annotation file: export coco replaces only an earlier export",
            out.display()
        ),
        "choose a new file name",
    ))
}
