//! Argument structs (clap derive). Doc comments are the help text.

use std::path::PathBuf;

use clap::{Args, Parser, Subcommand, ValueEnum};

mod train;
pub use train::{DeviceArg, EvalArgs, ModelArg, ScheduleArg, TrainArgs};

#[derive(Debug, Parser)]
#[command(
    name = "synthgen",
    version,
    about = "Synthetic RGB-D training data for 6-DoF object pose estimation",
    long_about = "Synthetic RGB-D training data for 6-DoF object pose estimation.\n\n\
        synthgen renders 3D object models in randomized scenes with its embedded CPU renderer \
        and writes RGB, depth, instance masks and poses as a BOP dataset that bop_toolkit and \
        BlenderProc users can load unchanged.",
    after_long_help = "Examples:\n  \
        synthgen render --objects drill.obj\n  \
        synthgen render --objects obj_000008.ply obj_000001.ply --camera linemod --frames 1000 --seed 7 --out out/lm\n  \
        synthgen render --scene scenes/tabletop.toml --objects drill.obj --frames 200"
)]
pub struct Cli {
    /// Print only warnings and errors; no progress bar.
    #[arg(long, short, global = true)]
    pub quiet: bool,

    #[command(subcommand)]
    pub command: Command,
}

#[derive(Debug, Subcommand)]
pub enum Command {
    /// Render randomized scenes of object models and write a BOP dataset.
    #[command(after_long_help = RENDER_EXAMPLES)]
    Render(Box<RenderArgs>),
    /// Train a pose model (TNet) on a BOP dataset; checkpoints, metrics and a curve.
    #[command(after_long_help = train::TRAIN_EXAMPLES)]
    Train(Box<TrainArgs>),
    /// Score pose estimates (a BOP results CSV or a checkpoint) against a dataset's GT.
    #[command(after_long_help = train::EVAL_EXAMPLES)]
    Eval(Box<EvalArgs>),
}

const RENDER_EXAMPLES: &str = "Examples:
  # A YCB drill in metres, 100 frames into data/synth (the defaults):
  synthgen render --objects drill.obj

  # Two Linemod models (millimetres), Linemod camera, fixed seed:
  synthgen render --objects obj_000008.ply obj_000001.ply --camera linemod --frames 1000 --seed 7 --out out/lm

  # Scene settings from a TOML file, some overridden by flags:
  synthgen render --scene scenes/tabletop.toml --objects drill.obj --distance-m 0.4..0.8

Output (BOP layout, loadable by bop_toolkit):
  OUT/camera.json, OUT/models/obj_XXXXXX.ply (mm), OUT/models/models_info.json,
  OUT/train_pbr/SCENE/{rgb,depth,mask,mask_visib}/, scene_camera.json, scene_gt.json,
  scene_gt_info.json, and OUT/synthgen.json (how to make the dataset again).";

#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum Backend {
    /// The embedded CPU rasterizer (default; no GPU, Python or Blender needed).
    Cpu,
    /// Blender (bpy, Cycles) through PyO3; needs the `blender` cargo feature.
    Blender,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum UnitsArg {
    /// Decide per file from the bounding box (a diagonal over 5 units means millimetres).
    Auto,
    Mm,
    M,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum RgbFormat {
    Png,
    Jpg,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum OrientationArg {
    /// Model +z up, random rotation about z.
    Upright,
    /// Uniformly random 3D rotation, resting on its lowest point.
    Random,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum BackgroundArg {
    Color,
    Noise,
    Images,
}

#[derive(Debug, Args)]
pub struct RenderArgs {
    /// Object meshes (.ply, .obj, .gltf, .glb); one instance of each per frame.
    #[arg(long, num_args = 1.., value_name = "MESH")]
    pub objects: Vec<PathBuf>,

    /// BOP object ids for --objects, in order (default: the number in `obj_000008.ply`-style
    /// names, else 1, 2, ... avoiding ids already taken).
    #[arg(long, value_delimiter = ',', value_name = "ID,...")]
    pub obj_ids: Vec<u32>,

    /// Units of the mesh coordinates.
    #[arg(long, value_enum, default_value_t = UnitsArg::Auto)]
    pub units: UnitsArg,

    /// Number of frames to render.
    #[arg(long, default_value_t = 100)]
    pub frames: u64,

    /// Index of the first frame (frames are numbered globally, so runs with different ranges
    /// can be combined).
    #[arg(long, default_value_t = 0)]
    pub first_frame: u64,

    /// Output dataset folder.
    #[arg(long, default_value = "data/synth")]
    pub out: PathBuf,

    /// Write into a non-empty --out folder, replacing files with the same names.
    #[arg(long)]
    pub force: bool,

    /// Global seed; frame i is a pure function of (seed, i).
    #[arg(long, default_value_t = 0)]
    pub seed: u64,

    /// Scene spec (TOML): camera, placement, lights, background, materials. Flags override it.
    #[arg(long, value_name = "FILE")]
    pub scene: Option<PathBuf>,

    /// Camera preset: linemod, d455, d455-720, ycbv.
    #[arg(long)]
    pub camera: Option<String>,

    /// Explicit intrinsics "fx,fy,cx,cy" in pixels (overrides the preset's).
    #[arg(long, value_name = "FX,FY,CX,CY", value_delimiter = ',')]
    pub camera_k: Option<Vec<f64>>,

    /// Image width and height in pixels (overrides the preset's).
    #[arg(long, value_name = "W,H", value_delimiter = ',')]
    pub image_size: Option<Vec<u32>>,

    /// Camera distance from the look-at point, metres, as MIN..MAX.
    #[arg(long, value_name = "MIN..MAX", value_parser = parse_range)]
    pub distance_m: Option<[f64; 2]>,

    /// Camera elevation above the ground plane, degrees, as MIN..MAX.
    #[arg(long, value_name = "MIN..MAX", value_parser = parse_range)]
    pub elevation_deg: Option<[f64; 2]>,

    /// How objects rest on the ground plane.
    #[arg(long, value_enum)]
    pub orientation: Option<OrientationArg>,

    /// What fills pixels where no geometry is.
    #[arg(long, value_enum)]
    pub background: Option<BackgroundArg>,

    /// Folder of PNG/JPEG images for `--background images`.
    #[arg(long, value_name = "DIR")]
    pub background_dir: Option<PathBuf>,

    /// Renderer.
    #[arg(long, value_enum, default_value_t = Backend::Cpu)]
    pub backend: Backend,

    /// BOP split folder name.
    #[arg(long, default_value = "train_pbr")]
    pub split: String,

    /// Frames per scene folder (BOP PBR sets use 1000).
    #[arg(long, default_value_t = 1000)]
    pub chunk_size: u32,

    /// RGB image format.
    #[arg(long, value_enum, default_value_t = RgbFormat::Png)]
    pub rgb_format: RgbFormat,

    /// JPEG quality for `--rgb-format jpg`.
    #[arg(long, default_value_t = 95, value_parser = clap::value_parser!(u8).range(1..=100))]
    pub jpg_quality: u8,

    /// Depth PNG unit in millimetres: stored value = depth_mm / depth_scale. 0.1 (BlenderProc's
    /// PBR sets) reaches 6.5 m; 1.0 (Linemod) reaches 65 m.
    #[arg(long, default_value_t = 0.1)]
    pub depth_scale: f64,

    /// Visibility tolerance in metres for mask_visib (bop_toolkit's delta).
    #[arg(long, default_value_t = 0.015)]
    pub visib_delta_m: f64,

    /// Worker threads (default: all cores).
    #[arg(long, short)]
    pub jobs: Option<usize>,

    /// Stop at the first frame that fails instead of reporting failures at the end.
    #[arg(long)]
    pub fail_fast: bool,
}

/// Parses `MIN..MAX` (or a single value) into a closed range.
pub fn parse_range(s: &str) -> Result<[f64; 2], String> {
    let parse = |v: &str| {
        v.trim()
            .parse::<f64>()
            .map_err(|_| format!("{v:?} is not a number; expected MIN..MAX such as 0.6..1.1"))
    };
    let (lo, hi) = match s.split_once("..") {
        Some((a, b)) => (parse(a)?, parse(b)?),
        None => {
            let v = parse(s)?;
            (v, v)
        }
    };
    if !(lo.is_finite() && hi.is_finite()) || lo > hi {
        return Err(format!(
            "expected finite MIN..MAX with MIN <= MAX, got {s:?}"
        ));
    }
    Ok([lo, hi])
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ranges_parse() {
        assert_eq!(parse_range("0.6..1.1").unwrap(), [0.6, 1.1]);
        assert_eq!(parse_range("2").unwrap(), [2.0, 2.0]);
        assert!(parse_range("1..0").is_err());
        assert!(parse_range("a..b").is_err());
    }

    #[test]
    fn cli_is_consistent() {
        use clap::CommandFactory;
        Cli::command().debug_assert();
    }
}
