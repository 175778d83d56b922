//! Arguments of `synthgen experiment`.

use std::path::PathBuf;

use clap::{Args, Subcommand};
use synthgen_curate::mix::SceneRef;

use super::budget::TrainBudgetArgs;
use super::ModelArg;

#[derive(Debug, Subcommand)]
pub enum ExperimentCommand {
    /// The real/synthetic mixing table: for each composition of a fixed-size training set,
    /// mix, train the same model with the same budget, and test on the same held-out real frames.
    #[command(after_long_help = EXPERIMENT_MIX_EXAMPLES)]
    Mix(ExperimentMixArgs),
    /// Synthetic to real, measured on real frames: fit the scene and the sensor to real frames,
    /// render, train on synthetic only, and test on real frames, against baselines (TNet;
    /// --model rgb|rgb-dense: the RGB models on RGB-only photographs, GT boxes).
    #[command(after_long_help = super::sim2real::SIM2REAL_EXAMPLES)]
    Sim2real(super::sim2real::ExperimentSim2realArgs),
    /// The RGB model's table: centre + Tz against direct XYZ, trained on the same set and
    /// scored with 5cm5°, E_te and E_re per object on held-out frames.
    #[command(after_long_help = super::rgb::RGB_EXAMPLES)]
    Rgb(super::rgb::ExperimentRgbArgs),
}

pub const EXPERIMENT_MIX_EXAMPLES: &str = "Examples:
  # Your captures against a synthetic set rendered here from the same mesh:
  synthgen experiment mix --real data/lm_driller --objects obj_000008.ply --total 1000 --out runs/mix

  # No real data: a rendered stand-in (D455 noise with holes, other lights and backgrounds):
  synthgen experiment mix --real-proxy --objects driller.ply --epochs 6 --out runs/mix

  # Both sets given, three training seeds per row (mean ± std), the full model:
  synthgen experiment mix --real data/real --synth data/synth --model full --repeats 3

  # The whole pipeline in about a minute (small total, few epochs, tiny images):
  synthgen experiment mix --real-proxy --objects driller.ply --quick --out /tmp/mix

  # Real video (YCB-Video): test on a whole held-out scene, render the synthetic side from
  # the dataset's own annotated models, and add rows \"all 40 real + K× synthetic\":
  synthgen experiment mix --real ../shared/data/ycbv_real --scene scenes/ycbv_like.toml \
    --test-scenes 0 --total 40 --plus-synth 1,4,16 --out runs/mix_real

Rows (default: the study's 7 compositions of --total, real/synthetic):
  1500/0, 1250/250, 1000/500, 750/750, 500/1000, 250/1250, 0/1500 (for --total 1500).
--plus-synth K,... adds rows \"all the real training frames + K× as many synthetic\"
(named `real 40 + 4× synth 160`) after them; to run only those and the all-real
baseline, give --ratios R/0 with R the real training frames.
Every row is tested on the same real frames (`synthgen mix`'s test split depends on
--seed only, or is every frame of --test-scenes; its hash is recorded per row and
checked). Run it again with the same options to resume: finished rows are kept, an
unfinished row is redone.

Output (in --out):
  table.md, table.csv   real, synth, train error, test error (± std over --repeats),
                        ADD(-S) and 5cm5° accuracy for --model full; table.md also
                        the test error per object
  table_objects.csv     per row and test object: n, test error, training instances
                        (real, synthetic)
  plot.png              test error (y) against the synthetic fraction (x, 0..1),
                        error bars ±1 std; train error in grey; the --plus-synth rows
                        in green (joined to the all-real row when it has as many real
                        frames)
  rows/NAME/            mix/ (the mixed dataset), train/ (the run), row.json (config,
                        metrics, test-split hash, wall times; written last)
  sources/              rendered sets (--real-proxy, or --synth absent), reused on resume
  experiment.json       the settings; a re-run with other settings is refused";

#[derive(Debug, Args)]
pub struct ExperimentMixArgs {
    /// The real dataset (BOP, Linemod/DenseFusion or YCB-Video layout; the latter two are
    /// converted to BOP once): its held-out frames are the test set.
    #[arg(long, value_name = "DIR", required_unless_present = "real_proxy")]
    pub real: Option<PathBuf>,

    /// No real data: render a stand-in "real" set (scenes/real_proxy.toml: D455 camera, depth
    /// noise with holes, RGB noise, other lights, plain backgrounds, cylinder clutter, another seed).
    #[arg(long, conflicts_with = "real")]
    pub real_proxy: bool,

    /// The synthetic dataset (default: rendered from --scene and --objects into OUT/sources).
    #[arg(long, value_name = "DIR")]
    pub synth: Option<PathBuf>,

    /// Scene spec for the synthetic set rendered here (default: `synthgen render`'s defaults).
    #[arg(long, value_name = "FILE")]
    pub scene: Option<PathBuf>,

    /// Object meshes for the sets rendered here (--real-proxy, or --synth absent). Default
    /// with --real: the real dataset's annotated objects that have a model file, with their
    /// ids and units (an object without one is an error if it can be in the test split,
    /// else it is left out with a warning).
    #[arg(long, num_args = 1.., value_name = "MESH")]
    pub objects: Vec<PathBuf>,

    /// BOP object ids for --objects, in order (default: from the file names, else 1, 2, ...).
    #[arg(long, value_delimiter = ',', value_name = "ID,...")]
    pub obj_ids: Vec<u32>,

    #[arg(long, value_enum, default_value_t = ModelArg::Tnet)]
    pub model: ModelArg,

    /// Training frames per row (real + synthetic); the default rows divide it in sixths.
    /// [default: 1500; 42 with --quick; at most the real frames outside --test-scenes]
    #[arg(long)]
    pub total: Option<usize>,

    /// Rows as REAL/SYNTH frame counts, e.g. 1500/0,750/750,0/1500 (overrides --total's rows).
    #[arg(long, value_delimiter = ',', value_name = "R/S,...")]
    pub ratios: Vec<String>,

    /// Real frames held out for testing, the same for every row (default: --total / 5).
    #[arg(long)]
    pub test_count: Option<usize>,

    /// Test on every real frame of these scenes (ID, or SPLIT/ID for one split) and train on
    /// real frames of the other scenes only: for video captures, whose consecutive frames are
    /// near-duplicates. Instead of --test-count.
    #[arg(
        long,
        value_delimiter = ',',
        value_name = "ID,...",
        conflicts_with_all = ["test_count", "real_proxy"]
    )]
    pub test_scenes: Vec<SceneRef>,

    /// Also rows "all the real training frames + K× as many synthetic", one per K (e.g.
    /// 1,4,16), after the fixed-total rows.
    #[arg(long, value_delimiter = ',', value_name = "K,...")]
    pub plus_synth: Vec<usize>,

    #[command(flatten)]
    pub budget: TrainBudgetArgs,

    /// Seeds the mix (and so the test split) and the rendering; training seed = seed + repeat.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,

    /// Train each row this many times (training seeds seed, seed+1, ...): mean ± std.
    #[arg(long, default_value_t = 1, value_parser = crate::cli::size(1, 100))]
    pub repeats: usize,

    /// Small and fast, to check the pipeline: the --quick defaults above and rendered sets
    /// at a quarter of the camera's resolution (160x120 for 640x480); with --real the
    /// synthetic set keeps the scene's size (a mix has one image size).
    #[arg(long)]
    pub quick: bool,

    /// Output folder.
    #[arg(long, default_value = "runs/mix")]
    pub out: PathBuf,

    /// Start over in a non-empty --out that holds an experiment with other settings.
    #[arg(long)]
    pub force: bool,

    /// Worker threads (default: all cores).
    #[arg(long, short = 'j', value_parser = crate::cli::threads())]
    pub jobs: Option<usize>,
}
