//! Arguments of `synthgen sensor fit` and `synthgen sensor compare`.

use std::path::PathBuf;

use clap::{Args, Subcommand};

#[derive(Debug, Subcommand)]
pub enum SensorCommand {
    /// Fit the structured-light depth model to real frames with GT poses; write a sensor file.
    #[command(after_long_help = FIT_EXAMPLES)]
    Fit(SensorFitArgs),
    /// Compare two datasets' depth readings (real frames and their replay, usually), aspect by
    /// aspect.
    #[command(after_long_help = COMPARE_EXAMPLES)]
    Compare(SensorCompareArgs),
    /// Compare two datasets' colour images inside the real visible masks (real photographs
    /// and their replay, usually), per object.
    #[command(after_long_help = COMPARE_RGB_EXAMPLES)]
    CompareRgb(SensorCompareRgbArgs),
}

pub const COMPARE_RGB_EXAMPLES: &str = "Examples:
  # How close the embedded renderer's replay of the real YCB-Video frames comes to the
  # photographs, with the dataset's plain models and with aligned textured scans:
  synthgen render --replay ../shared/data/ycbv_real --format ycbv --out out/plain
  synthgen model align --scans ../shared/data/ycb_textured \\
      --to-dataset ../shared/data/ycbv_real --out models_tex
  synthgen render --replay ../shared/data/ycbv_real --replay-models models_tex \\
      --format ycbv --out out/tex
  synthgen sensor compare-rgb --real ../shared/data/ycbv_real --synth out/plain
  synthgen sensor compare-rgb --real ../shared/data/ycbv_real --synth out/tex

Frames are matched by scene and image id. Per frame, one gain per channel (exposure and white
balance) is fitted to the photograph over the compared pixels. Per instance, over the real
visible mask eroded by one pixel where the render is not black: the normalized
cross-correlation of the grey levels (ncc_int) and of their Sobel gradient magnitudes
(ncc_grad; edges, print, texture), and the Hellinger distance of the 16-bin colour
histograms (hist; 0 the same colours, 1 disjoint). Higher NCC and lower hist are closer.";

#[derive(Debug, Args)]
pub struct SensorCompareRgbArgs {
    /// The real photographs (BOP, Linemod or YCB-Video, with visible masks).
    #[arg(long, value_name = "DIR")]
    pub real: PathBuf,

    /// Their synthetic twins (`synthgen render --replay REAL`).
    #[arg(long, value_name = "DIR")]
    pub synth: PathBuf,

    /// Only these scene ids.
    #[arg(long, value_delimiter = ',', value_name = "ID,...")]
    pub scenes: Vec<u32>,

    /// Instances with fewer compared pixels are left out.
    #[arg(long, default_value_t = 200)]
    pub min_pixels: usize,

    /// Print the comparison as JSON on stdout (with every instance) instead of the table.
    #[arg(long)]
    pub json: bool,
}

pub const FIT_EXAMPLES: &str = "Examples:
  # Fit to the real YCB-Video frames; a figure of real vs fitted curves:
  synthgen sensor fit --data ../shared/data/ycbv_real --out sensors/asus_xtion.toml --plot fit.png

  # Fit on two scenes, keep the third for `sensor compare`:
  synthgen sensor fit --data ../shared/data/ycbv_real --scenes 1,2 --out xtion_12.toml

  # Use the fitted file:
  synthgen render --replay ../shared/data/ycbv_real --sensor xtion_12.toml --out out/replay

Every frame's objects are rendered at their GT poses (the clean depth) and the dataset's depth
readings on those pixels are measured: the hole run beside each silhouette edge against the
background's depth (shadow side and width -> baseline_m), holes by edge distance, incidence
and brightness (a maximum-likelihood fit), readings from behind the surface near edges
(edge_mix), the robust spread of the residuals after each instance's own offset and tilt
(GT poses are off by millimetres) by depth and incidence (disparity_sigma_px,
lateral_sigma_px), the median offset (bias_m) and foreground readings just outside edges
(fattening_px). Frames whose median |reading - clean depth| exceeds
--max-frame-residual-mm (GT obviously off) are listed and left out. The method and the
numbers on the shared frames: docs/sensors.md.";

pub const COMPARE_EXAMPLES: &str = "Examples:
  # How close is a sensor model to the real camera? Replay the real frames through it first:
  synthgen render --replay ../shared/data/ycbv_real --sensor sensors/asus_xtion.toml --out out/replay
  synthgen sensor compare --real ../shared/data/ycbv_real --synth out/replay --plot compare.png

  # Only scene 0 (a scene the fit did not see), as JSON:
  synthgen sensor compare --real ../shared/data/ycbv_real --synth out/replay --scenes 0 --json

Both datasets' objects are rendered at their own GT poses; their readings on those pixels
are compared: the Wasserstein-1 distance of the surface residuals (mm), hole rates overall,
by incidence and by edge distance, and the share of object readings across silhouette edges
(the edge profile). Each aspect is divided by its scale (1 mm, 0.05) and the overall score is
their mean: 0 = the same, lower = closer. Holes by brightness, readings of another surface,
shadow zones and bias are shown but not scored. Per scene and per object lines follow.";

#[derive(Debug, Args)]
pub struct SensorFitArgs {
    /// The real dataset (BOP, Linemod or YCB-Video) with depth images and GT poses.
    #[arg(long, value_name = "DIR")]
    pub data: PathBuf,

    /// The sensor file to write (TOML; `render --sensor FILE` takes it).
    #[arg(long, value_name = "FILE")]
    pub out: PathBuf,

    /// Overwrite --out when it exists.
    #[arg(long)]
    pub force: bool,

    /// Only these scene ids (e.g. the training scenes of a leave-one-scene-out split).
    #[arg(long, value_delimiter = ',', value_name = "ID,...")]
    pub scenes: Vec<u32>,

    /// Leave out frames whose median |reading - clean depth| over the object pixels is above
    /// this (their GT is obviously off), millimetres.
    #[arg(long, default_value_t = 20.0, value_name = "MM")]
    pub max_frame_residual_mm: f64,

    /// A sensor file whose [structured_light] values start the fit and give the parameters it
    /// does not fit (focal_px, subpixel, range_m, edge_jump_rel, depth_unit_m).
    #[arg(long, value_name = "FILE")]
    pub base: Option<PathBuf>,

    /// Write a PNG of the real statistics (dots) and the fitted model (lines).
    #[arg(long, value_name = "PNG")]
    pub plot: Option<PathBuf>,

    /// Print the full report as JSON on stdout instead of the text summary.
    #[arg(long)]
    pub json: bool,

    /// Worker threads (default: all cores).
    #[arg(long, short, value_parser = crate::cli::threads())]
    pub jobs: Option<usize>,
}

#[derive(Debug, Args)]
pub struct SensorCompareArgs {
    /// The first dataset: the real frames.
    #[arg(long, value_name = "DIR")]
    pub real: PathBuf,

    /// The second dataset: usually the real one replayed through a sensor model
    /// (`synthgen render --replay REAL --sensor FILE`).
    #[arg(long, value_name = "DIR")]
    pub synth: PathBuf,

    /// Only these scene ids, in both datasets.
    #[arg(long, value_delimiter = ',', value_name = "ID,...")]
    pub scenes: Vec<u32>,

    /// Write a PNG of the hole rates by bin and the edge profiles of both.
    #[arg(long, value_name = "PNG")]
    pub plot: Option<PathBuf>,

    /// Print the comparison as JSON on stdout instead of the text table.
    #[arg(long)]
    pub json: bool,

    /// Worker threads (default: all cores).
    #[arg(long, short, value_parser = crate::cli::threads())]
    pub jobs: Option<usize>,
}
