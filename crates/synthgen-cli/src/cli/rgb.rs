//! Arguments of `synthgen experiment rgb`.

use std::path::PathBuf;

use clap::Args;

use super::TranslationArg;

pub const RGB_EXAMPLES: &str = "Examples:
  # Seed 001's Table 1 on Linemod objects: render a training set and a held-out test set
  # (another seed: other scenes, views and lights), train both variants, compare:
  M=../shared/data/lmo/models
  synthgen render --objects $M/obj_000001.ply $M/obj_000005.ply $M/obj_000006.ply \\
      $M/obj_000008.ply $M/obj_000009.ply --scene scenes/tabletop.toml --frames 2000 \\
      --seed 1 --out data/lm_rgb
  synthgen render --objects $M/obj_000001.ply $M/obj_000005.ply $M/obj_000006.ply \\
      $M/obj_000008.ply $M/obj_000009.ply --scene scenes/tabletop.toml --frames 300 \\
      --seed 2 --out data/lm_rgb_test
  synthgen experiment rgb --train data/lm_rgb --test data/lm_rgb_test --out runs/rgb

  # Real frames as the test set (their RGB and visible masks; scene 2 only):
  synthgen experiment rgb --train data/ycb_synth --test ../shared/data/ycbv_real \\
      --test-scenes 2 --out runs/rgb_real

  # The whole pipeline on tiny settings:
  synthgen experiment rgb --train data/lm_rgb --test data/lm_rgb_test --quick --out /tmp/rgb

Both variants see the same crops (the GT bbox_visib of each instance, squared and
jittered while training; no detector), the same box geometry, the same training set,
seed and budget; only the translation's parametrization differs (docs/training.md).
A re-run with the same options keeps the finished variants.

Output (in --out):
  table.md, table.csv   per object and variant: 5cm5° accuracy, mean E_te (cm), mean
                        E_re (°), ADD(-S) accuracy; the mean over objects (seed 001's
                        Table 1 layout), and per test scene
  report.json           the same numbers, the verdict, timings
  variants/NAME/        train/ (the run: model.safetensors, metrics.jsonl, curve.png),
                        scores.json (written last)
  experiment.json       the settings; a re-run with other settings is refused";

#[derive(Debug, Args)]
pub struct ExperimentRgbArgs {
    /// The training set (BOP, Linemod or YCB-Video layout; e.g. rendered by `synthgen render`).
    #[arg(long, value_name = "DIR")]
    pub train: PathBuf,

    /// The held-out test set (BOP, Linemod or YCB-Video layout): frames the training never
    /// saw, synthetic or real. Only its objects the training set has are scored.
    #[arg(long, value_name = "DIR")]
    pub test: PathBuf,

    /// The split of --train (default: `test` if present, else the only split).
    #[arg(long)]
    pub train_split: Option<String>,

    /// The split of --test (default: `test` if present, else the only split).
    #[arg(long)]
    pub test_split: Option<String>,

    /// Only these scene ids of --test are scored.
    #[arg(long, value_delimiter = ',', value_name = "ID,...")]
    pub test_scenes: Vec<u32>,

    /// The variants to train, in order.
    #[arg(long, value_enum, value_delimiter = ',', default_values_t = [TranslationArg::CentreTz, TranslationArg::Xyz])]
    pub variants: Vec<TranslationArg>,

    /// Training epochs per variant. [default: 40; 2 with --quick]
    #[arg(long)]
    pub epochs: Option<usize>,

    /// Crops per step. [default: 32; 8 with --quick]
    #[arg(long)]
    pub batch: Option<usize>,

    /// Peak learning rate (AdamW, cosine schedule).
    #[arg(long, allow_negative_numbers = true, default_value_t = 2e-3)]
    pub lr: f64,

    /// Width of the fully connected layers. [default: 256; 32 with --quick]
    #[arg(long)]
    pub width: Option<usize>,

    /// Side of the input crop, pixels. [default: 64; 32 with --quick]
    #[arg(long)]
    pub crop_size: Option<u32>,

    /// Leave out (and do not score) instances less visible than this.
    #[arg(long, allow_negative_numbers = true, default_value_t = 0.1)]
    pub min_visib_fract: f64,

    /// Seeds the initialization, the shuffling, the box and colour jitter.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,

    /// Small and fast, to check the pipeline: the --quick defaults above.
    #[arg(long)]
    pub quick: bool,

    /// Output folder.
    #[arg(long, default_value = "runs/rgb")]
    pub out: PathBuf,

    /// Start over in a non-empty --out that holds an experiment with other settings.
    #[arg(long)]
    pub force: bool,

    /// Worker threads (default: all cores).
    #[arg(long, short = 'j', value_parser = crate::cli::threads())]
    pub jobs: Option<usize>,
}
