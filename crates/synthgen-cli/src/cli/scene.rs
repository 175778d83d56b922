//! Arguments of `synthgen scene fit`.

use std::path::PathBuf;

use clap::{Args, Subcommand};

#[derive(Debug, Subcommand)]
pub enum SceneCommand {
    /// Derive a scene spec (camera, camera pose, placement, objects) from real frames with GT
    /// poses (and depth, where there is some).
    #[command(after_long_help = FIT_EXAMPLES)]
    Fit(SceneFitArgs),
}

pub const FIT_EXAMPLES: &str = "Examples:
  # Fit to the real YCB-Video frames, then render training data like them (no --objects:
  # the scene lists the dataset's models):
  synthgen scene fit --data ../shared/data/ycbv_real --out scenes/fitted.toml
  synthgen render --scene scenes/fitted.toml --frames 1000 --out data/synth

  # Two scenes only, with a fitted depth sensor, the whole report as JSON:
  synthgen sensor fit --data ../shared/data/ycbv_real --out sensors/xtion.toml
  synthgen scene fit --data ../shared/data/ycbv_real --scenes 1,2 --sensor sensors/xtion.toml \\
      --out scenes/fitted_12.toml --json

  # RGB-only photographs (no depth): the table from the objects' poses:
  synthgen scene fit --data ../shared/data/lmo --out scenes/lmo_fitted.toml

Per frame, the table plane is fitted (RANSAC, 300 candidates, 5 mm inlier band, fixed seed)
to the real depth outside the objects' visible masks, its normal pointing up; in a frame
without depth (RGB-only data such as Linemod-Occluded's test images) it is the plane on which
the objects' lowest points at their GT poses agree best (at least 3 objects within 1 cm,
those on other objects left out). From it: the
camera's elevation (the angle between the optical axis and the table), its distance to the
look-at point (where the optical axis passes the height of the objects' mean centre, as
synthgen's sampler aims), the roll about the optical axis, and per object the model axis
closest to the table's normal (its `up`) and the angle between them (its tilt). The spec
gets the observed ranges widened by 3 degrees or 10 %, the azimuth all around (not
identifiable from a few videos), the numbers of objects per frame, the spread of their
centres on the table, and each object's model file (relative to --out), id, units, up axis
and largest tilt. Frames without a table plane are skipped with a warning. The method and
the numbers on the shared frames: docs/scenes.md.";

#[derive(Debug, Args)]
pub struct SceneFitArgs {
    /// The real dataset (BOP, Linemod or YCB-Video) with GT poses; depth images optional.
    #[arg(long, value_name = "DIR")]
    pub data: PathBuf,

    /// The scene spec to write (TOML; `render --scene FILE` takes it).
    #[arg(long, value_name = "FILE")]
    pub out: PathBuf,

    /// Overwrite --out when it exists.
    #[arg(long)]
    pub force: bool,

    /// Only these scene ids.
    #[arg(long, value_delimiter = ',', value_name = "ID,...")]
    pub scenes: Vec<u32>,

    /// A sensor file (`synthgen sensor fit` writes one) for the scene's `[sensor] file`;
    /// without it the scene has no sensor model.
    #[arg(long, value_name = "FILE")]
    pub sensor: Option<PathBuf>,

    /// Print the full report as JSON on stdout instead of the text summary.
    #[arg(long)]
    pub json: bool,
}
