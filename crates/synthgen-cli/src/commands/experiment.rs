//! `synthgen experiment mix|sim2real|rgb`: skins over `synthgen_experiment`. The flags map
//! onto its options (the command line is what the runs record as their reproducing command);
//! the report it returns is printed.

use anyhow::Result;
use synthgen_experiment::options::{
    MixOptions, Model, Refine, RgbOptions, Sim2realModel, Sim2realOptions, TrainBudgetOptions,
};
use synthgen_experiment::Log;
use synthgen_train::models::rgb::Translation;

use crate::cli::{
    ExperimentMixArgs, ExperimentRgbArgs, ExperimentSim2realArgs, ModelArg, RefineArg,
    Sim2realModelArg, TrainBudgetArgs, TranslationArg,
};
use crate::{ExitStatus, Printer};

pub fn run_mix(args: ExperimentMixArgs, printer: &Printer) -> Result<ExitStatus> {
    let md = synthgen_experiment::run_mix(mix_options(args), &Log::new(printer))?;
    printer.data(&md)?;
    Ok(ExitStatus::Success)
}

pub fn run_sim2real(args: ExperimentSim2realArgs, printer: &Printer) -> Result<ExitStatus> {
    let md = synthgen_experiment::sim2real::run(sim2real_options(args), &Log::new(printer))?;
    printer.data(&md)?;
    Ok(ExitStatus::Success)
}

pub fn run_rgb(args: ExperimentRgbArgs, printer: &Printer) -> Result<ExitStatus> {
    let md = synthgen_experiment::rgb::run(rgb_options(args), &Log::new(printer))?;
    printer.data(&md)?;
    Ok(ExitStatus::Success)
}

fn model(m: ModelArg) -> Model {
    match m {
        ModelArg::Tnet => Model::Tnet,
        ModelArg::Rnet => Model::Rnet,
        ModelArg::Full => Model::Full,
    }
}

fn budget(b: TrainBudgetArgs) -> TrainBudgetOptions {
    TrainBudgetOptions {
        epochs: b.epochs,
        batch: b.batch,
        lr: b.lr,
        points: b.points,
        width: b.width,
    }
}

pub fn mix_options(a: ExperimentMixArgs) -> MixOptions {
    MixOptions {
        real: a.real,
        real_proxy: a.real_proxy,
        synth: a.synth,
        scene: a.scene,
        objects: a.objects,
        obj_ids: a.obj_ids,
        model: model(a.model),
        total: a.total,
        ratios: a.ratios,
        test_count: a.test_count,
        test_scenes: a.test_scenes,
        plus_synth: a.plus_synth,
        budget: budget(a.budget),
        seed: a.seed,
        repeats: a.repeats,
        quick: a.quick,
        out: a.out,
        force: a.force,
        jobs: a.jobs,
        command_line: std::env::args().collect(),
    }
}

pub fn sim2real_options(a: ExperimentSim2realArgs) -> Sim2realOptions {
    Sim2realOptions {
        fit: a.fit,
        test: a.test,
        test_scenes: a.test_scenes,
        model: match a.model {
            Sim2realModelArg::Tnet => Sim2realModel::Tnet,
            Sim2realModelArg::Rnet => Sim2realModel::Rnet,
            Sim2realModelArg::Full => Sim2realModel::Full,
            Sim2realModelArg::Rgb => Sim2realModel::Rgb,
            Sim2realModelArg::RgbDense => Sim2realModel::RgbDense,
        },
        frames: a.frames,
        scene: a.scene,
        models: a.models,
        cycles_frames: a.cycles_frames,
        budget: budget(a.budget),
        ablation: a.ablation,
        unseen_up: a.unseen_up,
        mask_jitter_px: a.mask_jitter_px,
        mask_shift_px: a.mask_shift_px,
        occlusion_prob: a.occlusion_prob,
        point_dropout: a.point_dropout,
        per_object: a.per_object,
        ensemble: a.ensemble,
        refine: match a.refine {
            RefineArg::None => Refine::None,
            RefineArg::Icp => Refine::Icp,
            RefineArg::Edges => Refine::Edges,
            RefineArg::Views => Refine::Views,
        },
        visible_box: a.visible_box.into(),
        seed: a.seed,
        rows: a.rows,
        max_failed_fraction: a.max_failed_fraction,
        detector: a.detector.into(),
        detector_epochs: a.detector_epochs,
        quick: a.quick,
        out: a.out,
        force: a.force,
        jobs: a.jobs,
        command_line: std::env::args().collect(),
    }
}

pub fn rgb_options(a: ExperimentRgbArgs) -> RgbOptions {
    RgbOptions {
        train: a.train,
        test: a.test,
        train_split: a.train_split,
        test_split: a.test_split,
        test_scenes: a.test_scenes,
        variants: a
            .variants
            .into_iter()
            .map(|v| match v {
                TranslationArg::CentreTz => Translation::CentreTz,
                TranslationArg::Xyz => Translation::Xyz,
            })
            .collect(),
        epochs: a.epochs,
        batch: a.batch,
        lr: a.lr,
        width: a.width,
        crop_size: a.crop_size,
        min_visib_fract: a.min_visib_fract,
        seed: a.seed,
        quick: a.quick,
        out: a.out,
        force: a.force,
        jobs: a.jobs,
        command_line: std::env::args().collect(),
    }
}

#[cfg(test)]
#[allow(clippy::unwrap_used)]
mod tests {
    use super::*;
    use clap::Parser;

    fn parse(argv: &[&str]) -> crate::cli::Command {
        crate::cli::Cli::try_parse_from(argv).unwrap().command
    }

    /// The flags' defaults are the library's: a command with only the required flags gives
    /// the options' `Default` (the command line aside).
    #[test]
    fn flag_defaults_are_the_librarys_defaults() {
        let crate::cli::Command::Experiment(crate::cli::ExperimentCommand::Mix(a)) =
            parse(&["synthgen", "experiment", "mix", "--real-proxy"])
        else {
            panic!("not experiment mix");
        };
        let o = mix_options(a);
        assert_eq!(
            MixOptions {
                command_line: Vec::new(),
                ..o
            },
            MixOptions {
                real_proxy: true,
                ..MixOptions::default()
            }
        );
        let crate::cli::Command::Experiment(crate::cli::ExperimentCommand::Sim2real(a)) = parse(&[
            "synthgen",
            "experiment",
            "sim2real",
            "--fit",
            "F",
            "--test",
            "T",
        ]) else {
            panic!("not experiment sim2real");
        };
        let o = sim2real_options(a);
        assert_eq!(
            Sim2realOptions {
                command_line: Vec::new(),
                ..o
            },
            Sim2realOptions {
                fit: Some("F".into()),
                test: "T".into(),
                ..Sim2realOptions::default()
            }
        );
        let crate::cli::Command::Experiment(crate::cli::ExperimentCommand::Rgb(a)) = parse(&[
            "synthgen",
            "experiment",
            "rgb",
            "--train",
            "A",
            "--test",
            "B",
        ]) else {
            panic!("not experiment rgb");
        };
        let o = rgb_options(a);
        assert_eq!(
            RgbOptions {
                command_line: Vec::new(),
                ..o
            },
            RgbOptions {
                train: "A".into(),
                test: "B".into(),
                ..RgbOptions::default()
            }
        );
    }
}
