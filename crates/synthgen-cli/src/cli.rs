//! Argument structs (clap derive). Doc comments are the help text.

use std::path::PathBuf;

use clap::{Args, Parser, Subcommand, ValueEnum};
use synthgen_curate::mix::SceneRef;

mod budget;
mod detector;
mod experiment;
mod model;
mod predict;
mod rgb;
mod ros;
mod scale;
mod scene;
mod sensor;
mod sim2real;
mod train;
pub use budget::TrainBudgetArgs;
pub use detector::{
    BboxTypeArg, DetectorCommand, DetectorEvalArgs, DetectorRunArgs, DetectorTrainArgs,
};
pub use experiment::{ExperimentCommand, ExperimentMixArgs};
pub use model::{ModelAlignArgs, ModelCommand};
pub use predict::{PredictArgs, RefineArgs, PREDICT_EXAMPLES};
pub use rgb::ExperimentRgbArgs;
pub use ros::{RosArgs, ROS_EXAMPLES};
pub use scale::{MergeArgs, Shard, MERGE_EXAMPLES};
pub use scene::{SceneCommand, SceneFitArgs};
pub use sensor::{SensorCommand, SensorCompareArgs, SensorCompareRgbArgs, SensorFitArgs};
pub use sim2real::{ExperimentSim2realArgs, RefineArg, Sim2realModelArg};
pub use train::{
    DeviceArg, EvalArgs, ModelArg, RgbRefineArg, ScheduleArg, TrainArgs, TrainModelArg,
    TranslationArg, VisibleBoxArg,
};

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
        synthgen render --scene scenes/tabletop.toml --objects drill.obj --frames 200\n\n\
        Output: data you ask for (tables, JSON, problem lists) on stdout; progress, summaries,\n\
        warnings and errors on stderr.\n\n\
        Exit status:\n  \
        0  success\n  \
        1  bad input: a usage error, a missing or broken file, an inconsistent dataset, frames or\n     \
        rows that failed (the others are written and reported), a diverged training\n  \
        2  internal error: a bug in synthgen (please report it)"
)]
pub struct Cli {
    /// Print only warnings and errors; no progress bar.
    #[arg(long, short, global = true)]
    pub quiet: bool,
    /// Largest max(|det R − 1|, |R Rᵀ − I|) accepted in rotations read from files (real
    /// annotations are approximate: LM-O's reach 1.4e-2).
    #[arg(long, allow_negative_numbers = true, global = true, value_name = "TOL", default_value_t = synthgen_core::pose::DEFAULT_ROTATION_TOLERANCE)]
    pub rotation_tolerance: f64,

    #[command(subcommand)]
    pub command: Command,
}

#[derive(Debug, Subcommand)]
pub enum Command {
    /// Render randomized scenes of object models and write a BOP (or Linemod) dataset.
    #[command(after_long_help = RENDER_EXAMPLES)]
    Render(Box<RenderArgs>),
    /// Draw a reproducible mix of a real and a synthetic dataset, with a held-out real test split.
    #[command(after_long_help = MIX_EXAMPLES)]
    Mix(MixArgs),
    /// Count frames, objects and instances; show visibility, distance, elevation and in-plane
    /// rotation distributions, of one dataset or several side by side.
    #[command(after_long_help = STATS_EXAMPLES)]
    Stats(StatsArgs),
    /// Draw a contact sheet of frames with their ground-truth poses overlaid.
    #[command(after_long_help = PREVIEW_EXAMPLES)]
    Preview(PreviewArgs),
    /// Browse datasets in the web browser: a local, read-only server (prints its address).
    #[command(after_long_help = VIEW_EXAMPLES)]
    View(ViewArgs),
    /// Write a dataset's annotations in another tool's format (COCO).
    #[command(subcommand)]
    Export(ExportCommand),
    /// Compute masks and scene_gt_info.json from the GT poses of a BOP dataset (real captures).
    #[command(after_long_help = ANNOTATE_EXAMPLES)]
    Annotate(AnnotateArgs),
    /// Convert a dataset between the BOP, Linemod and YCB-Video layouts.
    #[command(after_long_help = CONVERT_EXAMPLES)]
    Convert(ConvertArgs),
    /// Check a BOP, Linemod or YCB-Video dataset: files, image sizes, poses, masks, depth, ids.
    #[command(after_long_help = VALIDATE_EXAMPLES)]
    Validate(ValidateArgs),
    /// Train a pose model: TNet, RNet, Full (RGB-D); rgb, rgb-dense (RGB only).
    ///
    /// On a BOP or Linemod dataset; checkpoints, metrics and a curve. The RGB models read the
    /// colour crop of each object's box: the GT visible box, or a detector's (`synthgen
    /// detector train|run`, then `synthgen eval --detections`). `synthgen experiment sim2real`
    /// renders, trains on synthetic frames only and scores on real frames in one command.
    #[command(after_long_help = train::TRAIN_EXAMPLES)]
    Train(Box<TrainArgs>),
    /// Score pose estimates (a BOP results CSV or a checkpoint) against a dataset's GT.
    #[command(after_long_help = train::EVAL_EXAMPLES)]
    Eval(Box<EvalArgs>),
    /// Combine the shard folders of a `synthgen render --shard I/N` run into one BOP dataset.
    #[command(after_long_help = MERGE_EXAMPLES)]
    Merge(MergeArgs),
    /// Find objects' boxes in whole frames, so the RGB models run without GT boxes: train the
    /// detector, run it into BOP detections.
    #[command(subcommand)]
    Detector(DetectorCommand),
    /// Poses from frames with no GT: the detector, then a pose model, on photographs (with
    /// their camera's intrinsics), a dataset's frames or a ROS 2 bag; BOP results and JSON
    /// lines.
    #[command(after_long_help = PREDICT_EXAMPLES)]
    Predict(Box<PredictArgs>),
    /// A ROS 2 node (no ROS installation needed): subscribes a camera's images and camera
    /// info, publishes vision_msgs Detection3DArray (a pose per object) and Detection2DArray.
    #[command(after_long_help = ROS_EXAMPLES)]
    Ros(Box<RosArgs>),
    /// Run an experiment end to end: the mixing table, synthetic to real, the RGB model's table.
    ///
    /// `mix`: the real/synthetic mixing table (mix, train, evaluate per composition).
    /// `sim2real`: fit, render, train on synthetic frames only and score on real frames (TNet
    /// on RGB-D frames; `synthgen experiment sim2real --model rgb-dense` on RGB-only
    /// photographs, with GT boxes). `rgb`: the RGB model's centre + Tz against direct XYZ.
    /// Without GT boxes, the RGB models take a detector's (`synthgen detector train|run`, then
    /// `synthgen eval --detections`).
    #[command(subcommand)]
    Experiment(ExperimentCommand),
    /// Fit a depth-sensor model to real frames, or compare two datasets' depth readings.
    #[command(subcommand)]
    Sensor(SensorCommand),
    /// Derive a scene spec from real frames with GT poses (and depth, where there is some).
    #[command(subcommand)]
    Scene(SceneCommand),
    /// Work on object models: align a textured scan to the model a dataset's poses refer to.
    #[command(subcommand)]
    Model(ModelCommand),
}

const ANNOTATE_EXAMPLES: &str = "Examples:
  # Real captures with rgb/, depth/, scene_camera.json and scene_gt.json per scene folder:
  synthgen annotate data/real

  # Only the test split, a 10 mm visibility tolerance:
  synthgen annotate data/real --split test --visib-delta-m 0.01

  # Compare the computed visible masks with YCB-Video's own label.png; write nothing there:
  synthgen annotate ../shared/data/ycbv_real --compare --report iou.json --overlay overlays/

Writes mask/ and mask_visib/ PNGs and scene_gt_info.json in each scene folder, as
bop_toolkit's calc_gt_masks.py and calc_gt_info.py: every object is rendered alone at its
pose with the embedded renderer (models/obj_XXXXXX.ply, millimetres); a pixel of its
silhouette is visible when the object's surface is at most --visib-delta-m behind the real
depth PNG's along the pixel's ray, or the depth PNG has no reading there (bop19 rule); without
a depth PNG the rendered scene depth is used. When the dataset already has visible masks,
the computed ones are compared with them first (IoU per instance: median and 10th
percentile per scene and per object).";

#[derive(Debug, Args)]
pub struct AnnotateArgs {
    /// Dataset folder: BOP with models/ and per scene scene_camera.json and scene_gt.json; with
    /// --compare any layout (YCB-Video, Linemod).
    pub dir: PathBuf,

    /// Compute the visible masks and compare them with the dataset's own; write nothing into
    /// the dataset.
    #[arg(long)]
    pub compare: bool,

    /// Write the comparison (per instance, per scene, per object) as JSON to this file.
    #[arg(long, value_name = "FILE")]
    pub report: Option<PathBuf>,

    /// Write overlay PNGs of computed (red) and dataset (blue) visible masks, green where both
    /// agree, into this folder.
    #[arg(long, value_name = "DIR")]
    pub overlay: Option<PathBuf>,

    /// How many frames get an overlay (spread evenly).
    #[arg(long, default_value_t = 12, value_name = "N", value_parser = size(0, 10_000))]
    pub overlay_count: usize,

    /// Only this split (default: all).
    #[arg(long)]
    pub split: Option<String>,

    /// Visibility tolerance in metres (bop_toolkit's delta).
    #[arg(long, allow_negative_numbers = true, default_value_t = 0.015)]
    pub visib_delta_m: f64,

    /// Stop at the first frame that fails instead of reporting failures at the end.
    #[arg(long)]
    pub fail_fast: bool,
}

#[derive(Debug, Subcommand)]
pub enum ExportCommand {
    /// COCO instance annotations (scene_gt_coco.json, as bop_toolkit's calc_gt_coco.py).
    #[command(after_long_help = COCO_EXAMPLES)]
    Coco(CocoArgs),
}

const COCO_EXAMPLES: &str = "Examples:
  # scene_gt_coco.json in every scene folder of train_pbr:
  synthgen export coco data/synth

  # One file for the test split, compressed RLE (pycocotools' string counts):
  synthgen export coco data/mix --split test --rle compressed --out data/mix/test_coco.json

Per visible instance: segmentation = RLE of mask_visib (column-major, as pycocotools),
bbox = bbox_visib, area = visible pixels, iscrowd 0, ignore = visib_fract below
--ignore-below. Categories are the object ids of models_info.json.";

#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum RleArg {
    /// Integer run lengths (bop_toolkit's default).
    Uncompressed,
    /// pycocotools' compressed string counts.
    Compressed,
}

#[derive(Debug, Args)]
pub struct CocoArgs {
    /// Dataset folder (BOP).
    pub dir: PathBuf,

    /// Split to export.
    #[arg(long, default_value = "train_pbr")]
    pub split: String,

    /// Write one file for the whole split here instead of scene_gt_coco.json per scene.
    #[arg(long, value_name = "FILE")]
    pub out: Option<PathBuf>,

    /// Mark instances with visib_fract below this as "ignore".
    #[arg(long, allow_negative_numbers = true, default_value_t = 0.1)]
    pub ignore_below: f64,

    /// RLE flavour of the masks.
    #[arg(long, value_enum, default_value_t = RleArg::Uncompressed)]
    pub rle: RleArg,
}

const STATS_EXAMPLES: &str = "Examples:
  synthgen stats data/synth
  synthgen stats data/mix --json > stats.json
  synthgen stats data/real --plot plots/

  # Real frames next to a synthetic set of the same objects (shares of each one's instances):
  synthgen stats out/ycbv_bop out/synth --plot plots/

Distances are ||cam_t_m2c|| per instance. Elevations are the camera's angle above the world
xy plane seen from the object when scene_camera.json has cam_R_w2c/cam_t_w2c (synthgen's,
BlenderProc's and YCB-Video's data), else above the object's own xy plane. In-plane rotation
is the camera's roll about the ray to the object: the angle from the image's up to the world's
(else the object's) up seen there; 0 is an upright camera.";

const PREVIEW_EXAMPLES: &str = "Examples:
  synthgen preview data/synth --out sheet.png
  synthgen preview /data/bop/lmo --split test --count 9 --seed 3 --out lmo.png

Each object gets its 3D bounding box (from models/models_info.json) in a colour of its own,
its axes (x red, y green, z blue, half the diameter long) and its id. Works on any BOP
dataset with models_info.json.";

#[derive(Debug, Args)]
pub struct StatsArgs {
    /// Dataset folder (BOP, Linemod or YCB-Video); several (up to 4) are shown side by side on
    /// shared bins, e.g. real frames next to a synthetic set.
    #[arg(value_name = "DIR", required = true, num_args = 1..=4)]
    pub dirs: Vec<PathBuf>,

    /// Print JSON instead of a table.
    #[arg(long)]
    pub json: bool,

    /// Also write PNG bar charts into this folder.
    #[arg(long, value_name = "DIR")]
    pub plot: Option<PathBuf>,
}

pub const VIEW_EXAMPLES: &str = "Examples:
  # Browse a dataset: open the printed address (http://127.0.0.1:8765/) in a browser
  synthgen view out/lm

  # Real frames and a synthetic set side by side (the statistics page overlays them)
  synthgen view data/real out/synth

  # Estimated poses (dashed, white) beside the GT, with their ADD(-S), E_te and E_re
  synthgen view out/lm --results results.csv

The server only reads: it serves the datasets' images and annotations and never writes into
them; it refuses any path outside them. It binds 127.0.0.1 unless --host says otherwise;
Ctrl-C stops it. See docs/view.md.";

#[derive(Debug, Args)]
pub struct ViewArgs {
    /// Dataset folders (BOP, Linemod or YCB-Video), up to 4.
    #[arg(value_name = "DIR", required = true, num_args = 1..=4)]
    pub dirs: Vec<PathBuf>,

    /// A BOP results CSV: its estimates are matched to the first dataset's GT and drawn.
    #[arg(long, value_name = "CSV")]
    pub results: Option<PathBuf>,

    /// Address to listen on (127.0.0.1: this machine only).
    #[arg(long, default_value = "127.0.0.1")]
    pub host: std::net::IpAddr,

    /// Port (0: any free port).
    #[arg(long, default_value_t = 8765)]
    pub port: u16,
}

#[derive(Debug, Args)]
pub struct PreviewArgs {
    /// Dataset folder (BOP).
    pub dir: PathBuf,

    /// Output PNG.
    #[arg(long, default_value = "preview.png")]
    pub out: PathBuf,

    /// Frames on the sheet.
    #[arg(long, default_value_t = 16, value_parser = size(1, 10_000))]
    pub count: usize,

    /// Seed of the choice of frames.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,

    /// Only frames of this split (default: all splits).
    #[arg(long)]
    pub split: Option<String>,

    /// Width of one frame on the sheet, pixels.
    #[arg(long, default_value_t = 320, value_parser = clap::value_parser!(u32).range(16..=4096))]
    pub tile_width: u32,
}

const MIX_EXAMPLES: &str = "Examples:
  # 1000 real + 500 synthetic training frames, 150 real test frames held out:
  synthgen mix --real data/real --synth data/synth --real-count 1000 --synth-count 500 --test-count 150 --out data/mix

  # The short form: counts only, paths from synthgen.toml or SYNTHGEN_REAL / SYNTHGEN_SYNTH:
  synthgen mix --real 1000 --synth 500

  # 30% synthetic out of 1500 training frames:
  synthgen mix --real data/real --synth data/synth --ratio 0.3 --total 1500

  # Video captures: test on whole scenes (every frame of YCB-Video scene 2), train on the others:
  synthgen mix --real data/ycbv --synth data/synth --real-count 40 --synth-count 160 --test-scenes 2

Project config (synthgen.toml, looked up in the current folder and its parents; paths
relative to the file):
  [mix]
  real = \"data/real\"
  synth = \"data/synth\"
  out = \"data/mix\"

Output (BOP layout): OUT/train/SCENE/ (real and synthetic, new image ids), OUT/test/SCENE/
(held-out real frames, the same for every count and ratio with the same seed and
--test-count or --test-scenes), OUT/camera.json, OUT/models/, OUT/provenance.json (source
of every frame) and OUT/synthgen.json (with --test-scenes, its list).";

/// The flags of `subcommands` (e.g. `["detector", "train"]`) given on this process's command
/// line, not defaulted: `--resume` compares those with the run it continues. The command line
/// is parsed again (it parsed once already, so this cannot fail differently).
pub fn explicit_flags(subcommands: &[&str]) -> Vec<String> {
    use clap::CommandFactory;
    let Ok(top) = Cli::command().try_get_matches_from(std::env::args_os()) else {
        return Vec::new();
    };
    let mut m = &top;
    for s in subcommands {
        match m.subcommand_matches(s) {
            Some(sub) => m = sub,
            None => return Vec::new(),
        }
    }
    m.ids()
        .filter(|id| m.value_source(id.as_str()) == Some(clap::parser::ValueSource::CommandLine))
        .map(|id| id.as_str().to_string())
        .collect()
}

/// `--jobs N`: worker threads, 1 to 1024 (a typo of 100000 would start as many threads).
pub fn threads() -> clap::builder::RangedU64ValueParser<usize> {
    size(1, 1024)
}

/// A count or size flag limited to `lo..=hi`: clap's message names the flag and the range.
pub fn size(lo: u64, hi: u64) -> clap::builder::RangedU64ValueParser<usize> {
    clap::builder::RangedU64ValueParser::<usize>::new().range(lo..=hi)
}

/// A dataset folder, or a frame count whose folder comes from the project config.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum PathOrCount {
    Path(PathBuf),
    Count(usize),
}

/// All digits is a count; anything else is a path (write `./1000` for a folder named 1000).
pub fn parse_path_or_count(s: &str) -> Result<PathOrCount, String> {
    if s.is_empty() {
        return Err("expected a dataset folder or a frame count".into());
    }
    if s.bytes().all(|b| b.is_ascii_digit()) {
        return s
            .parse()
            .map(PathOrCount::Count)
            .map_err(|_| format!("{s} is too large a count"));
    }
    Ok(PathOrCount::Path(PathBuf::from(s)))
}

#[derive(Debug, Args)]
pub struct MixArgs {
    /// The real dataset (BOP), or the number of real training frames (folder from the config).
    #[arg(long, value_name = "DIR|COUNT", value_parser = parse_path_or_count)]
    pub real: PathOrCount,

    /// The synthetic dataset (BOP), or the number of synthetic frames (folder from the config).
    #[arg(long, value_name = "DIR|COUNT", value_parser = parse_path_or_count)]
    pub synth: PathOrCount,

    /// Real training frames (with --real DIR).
    #[arg(long, conflicts_with_all = ["ratio", "total"])]
    pub real_count: Option<usize>,

    /// Synthetic training frames (with --synth DIR).
    #[arg(long, conflicts_with_all = ["ratio", "total"])]
    pub synth_count: Option<usize>,

    /// Synthetic fraction of the training frames (0..1), with --total.
    #[arg(long, allow_negative_numbers = true, requires = "total")]
    pub ratio: Option<f64>,

    /// Training frames in all, with --ratio.
    #[arg(long, requires = "ratio")]
    pub total: Option<usize>,

    /// Real frames held out as the test split (default: 10% of the real frames). Drawn first,
    /// from the seed alone, so it is the same for every count and ratio.
    #[arg(long)]
    pub test_count: Option<usize>,

    /// Hold out every real frame of these scenes as the test split (ID, or SPLIT/ID for one
    /// split) and draw the real training frames from the other scenes only. For video
    /// captures, whose consecutive frames are near-duplicates. Instead of --test-count.
    #[arg(
        long,
        value_delimiter = ',',
        value_name = "ID,...",
        conflicts_with = "test_count"
    )]
    pub test_scenes: Vec<SceneRef>,

    /// Output dataset folder (default: `out` from synthgen.toml, else data/mix).
    #[arg(long)]
    pub out: Option<PathBuf>,

    /// Replace a mix (or other output synthgen wrote) in a non-empty --out: everything in it
    /// is removed first; a folder holding other files is refused.
    #[arg(long)]
    pub force: bool,

    /// Leave out training frames that are the same images as held-out test frames (the same
    /// file, a hard link or the same bytes) instead of refusing the mix.
    #[arg(long)]
    pub exclude_shared: bool,

    /// Seed of the draw; the same seed and inputs give byte-identical output.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
}

const CONVERT_EXAMPLES: &str = "Examples:
  # A BOP dataset (e.g. from `synthgen render`) for DenseFusion:
  synthgen convert --to linemod data/synth data/synth_linemod

  # DenseFusion's Linemod_preprocessed into BOP (for bop_toolkit):
  synthgen convert --from linemod --to bop Linemod_preprocessed data/lm_bop

  # YCB-Video (PoseCNN's layout) into BOP, and back:
  synthgen convert --to bop ../shared/data/ycbv_real out/ycbv_bop
  synthgen convert --to ycbv out/ycbv_bop out/ycbv_again

YCB-Video -> BOP: poses copied (t metres -> mm), label.png -> mask_visib, models/<class>/
textured_simple.obj -> models/obj_NNNNNN.ply (mm); mask/ and scene_gt_info.json from the
models rendered at the GT poses (the visible counts from the labels). BOP -> YCB-Video: the
label from mask_visib; vertmap, center and -box.txt from the render; -meta.mat with the keys,
shapes and types scipy.io.loadmat gives for YCB-Video's own.

What maps to what (docs/formats.md has the details):
  cam_R_m2c, cam_t_m2c (mm), obj_id, cam_K   both ways, exactly
  rgb, depth                                 both ways; depth values copied when the depth
                                             scales agree, else rescaled (BOP 0.1 mm -> Linemod
                                             1 mm loses the sub-millimetre digit)
  BOP mask_visib  <->  Linemod mask          for objects with visib_fract >= --min-visib-fract
  BOP bbox_obj     ->  Linemod obj_bb
  BOP mask, scene_gt_info.json, symmetries   not in Linemod: lost on the way there";

const VALIDATE_EXAMPLES: &str = "Examples:
  synthgen validate data/synth
  synthgen validate Linemod_preprocessed --format linemod --max-problems 20
  synthgen validate data/synth --json > problems.json

Each problem is printed as `FILE: message` on stdout. Exit status: 0 when the dataset has no
problems, 1 when it has some (or cannot be read), 2 on an internal error.";

/// Dataset layouts.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum FormatArg {
    /// bop_toolkit / BlenderProc: camera.json, SPLIT/SCENE/{rgb,depth,mask,mask_visib}, scene_*.json.
    Bop,
    /// DenseFusion's Linemod_preprocessed: data/NN/{rgb,depth,mask}, gt.yml, info.yml.
    Linemod,
    /// YCB-Video (PoseCNN, DenseFusion): data/NNNN/NNNNNN-{color,depth,label}.png, -meta.mat,
    /// -box.txt, classes.txt, models/<class>/.
    Ycbv,
}

#[derive(Debug, Args)]
pub struct ConvertArgs {
    /// Layout of IN (default: detected from its files).
    #[arg(long, value_enum)]
    pub from: Option<FormatArg>,

    /// Layout to write.
    #[arg(long, value_enum)]
    pub to: FormatArg,

    /// Dataset to read.
    #[arg(value_name = "IN")]
    pub input: PathBuf,

    /// Folder to write (must be empty or absent unless --force).
    #[arg(value_name = "OUT")]
    pub output: PathBuf,

    /// Depth PNG unit of the output in millimetres (default: 1.0 for Linemod, as DenseFusion
    /// assumes; the source's for BOP; 0.1 for YCB-Video, i.e. factor_depth 10000).
    #[arg(long, allow_negative_numbers = true)]
    pub depth_scale: Option<f64>,
    /// To YCB-Video: the classes.txt to write (line i names object id i). Default: the names a
    /// conversion from YCB-Video recorded in IN/synthgen.json, else obj_NNNNNN.
    #[arg(long, value_name = "FILE")]
    pub classes: Option<PathBuf>,

    /// To Linemod: an object gets a folder entry (rgb, depth, mask) for a frame when its
    /// visib_fract is at least this.
    #[arg(long, allow_negative_numbers = true, default_value_t = 0.1)]
    pub min_visib_fract: f64,

    /// Replace the output in a non-empty OUT that synthgen wrote (everything in it is removed
    /// first); a folder holding other files is refused.
    #[arg(long)]
    pub force: bool,
}

#[derive(Debug, Args)]
pub struct ValidateArgs {
    /// Dataset folder.
    #[arg(value_name = "DIR")]
    pub dir: PathBuf,

    /// Layout of DIR (default: camera.json means BOP, classes.txt beside data/ YCB-Video,
    /// data/NN/gt.yml Linemod).
    #[arg(long, value_enum)]
    pub format: Option<FormatArg>,

    /// Print at most this many problems (all are counted; 0 prints all).
    #[arg(long, default_value_t = 50, value_name = "N")]
    pub max_problems: usize,

    /// Print the report as JSON on stdout (all problems), for scripts.
    #[arg(long)]
    pub json: bool,
}

const RENDER_EXAMPLES: &str = "Examples:
  # A YCB drill in metres, 100 frames into data/synth (the defaults):
  synthgen render --objects drill.obj

  # Two Linemod models (millimetres), Linemod camera, fixed seed:
  synthgen render --objects obj_000008.ply obj_000001.ply --camera linemod --frames 1000 --seed 7 --out out/lm

  # Scene settings from a TOML file, some overridden by flags:
  synthgen render --scene scenes/tabletop.toml --objects drill.obj --distance-m 0.4..0.8

  # DenseFusion's Linemod layout instead of BOP:
  synthgen render --objects obj_000008.ply --format linemod --out out/lm_linemod

  # A depth sensor model: a built-in one, or a sensor file (replaces the scene's [sensor]):
  synthgen render --objects drill.obj --sensor d455
  synthgen render --scene scenes/tabletop.toml --objects drill.obj --sensor my_xtion.toml

  # The synthetic twin of real frames: each frame re-rendered at its GT poses, camera and ids
  # (only the annotated objects, black background, clean depth unless --sensor):
  synthgen render --replay ../shared/data/ycbv_real --format ycbv --out out/ycbv_twin
  synthgen render --replay data/lmo --scenes 2 --sensor structured_light --seed 1 --out out/lmo_twin

Output (BOP layout, loadable by bop_toolkit):
  OUT/camera.json, OUT/models/obj_XXXXXX.ply (mm), OUT/models/models_info.json,
  OUT/train_pbr/SCENE/{rgb,depth,mask,mask_visib}/, scene_camera.json, scene_gt.json,
  scene_gt_info.json, and OUT/synthgen.json (how to make the dataset again).
With --format linemod: OUT/data/NN/{rgb,depth,mask}/IIII.png, gt.yml, info.yml, train.txt,
  test.txt per object id NN, OUT/models/obj_NN.ply and models_info.yml (docs/formats.md).
With --replay: the source's scene and image ids (BOP, YCB-Video; Linemod numbers frames per
  object), the source frame's split unless --split, the dataset's own models; frames without
  GT poses are skipped (docs/rendering.md, \"Replaying real frames\").";

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

    /// Replace the output in a non-empty --out that synthgen wrote (everything in it is
    /// removed first); a folder holding other files is refused.
    #[arg(long)]
    pub force: bool,

    /// Global seed; frame i is a pure function of (seed, i).
    #[arg(long, default_value_t = 0)]
    pub seed: u64,

    /// Scene spec (TOML): camera, placement, lights, background, materials. Flags override it.
    #[arg(long, value_name = "FILE")]
    pub scene: Option<PathBuf>,

    /// Depth sensor model: none, d455, tof, structured_light, or a sensor file (TOML with the
    /// keys of a scene's [sensor] section, e.g. `depth = "structured_light"`). Replaces the
    /// scene spec's [sensor] section, except that the scene's [sensor.rgb] stays unless the
    /// file sets [rgb]. With --replay the default is none (the clean rendered depth).
    #[arg(long, value_name = "NAME|FILE")]
    pub sensor: Option<String>,

    /// Re-render every annotated frame of this real dataset (BOP, Linemod or YCB-Video) at its
    /// GT poses with its own camera, models and ids: only the annotated objects, on black.
    /// Takes no --objects, --frames, --scene or camera, pose and background flags; renders
    /// with the embedded CPU renderer, or Cycles with --backend blender.
    #[arg(
        long,
        value_name = "REAL_DIR",
        conflicts_with_all = [
            "objects", "obj_ids", "units", "frames", "first_frame", "shard",
            "camera", "camera_k", "image_size", "distance_m", "elevation_deg", "orientation",
            "background", "background_dir", "chunk_size",
        ]
    )]
    pub replay: Option<PathBuf>,

    /// With --replay: only the frames of these scene ids (e.g. --scenes 0,2 to leave scene 1
    /// out).
    #[arg(
        long,
        value_delimiter = ',',
        value_name = "ID,...",
        requires = "replay"
    )]
    pub scenes: Vec<u32>,

    /// With --replay: models to render instead of the dataset's own, one folder per object
    /// named as the dataset names it (YCB-Video's class, `003_cracker_box`; BOP's file stem,
    /// `obj_000005`) holding one mesh, e.g. textured scans that `synthgen model align` put in
    /// the dataset's model frame. Objects without a folder keep the dataset's model.
    #[arg(long, value_name = "DIR", requires = "replay")]
    pub replay_models: Option<PathBuf>,

    /// With --replay: light the replay instead of rendering it flat (ambient 1, no lights):
    /// one point light 0.5 m above the camera, the sky/ground environment light, cast
    /// shadows, ambient occlusion and GGX shading (docs/models.md) — the realistic raster on
    /// the real frames' poses, for `sensor compare-rgb`; with --backend blender the same
    /// light, environment and materials through Cycles.
    #[arg(long, requires = "replay")]
    pub replay_lit: bool,

    /// Camera preset: linemod, d455, d455-720, ycbv (YCB-Video's UW rig, scenes 0-59),
    /// ycbv-cmu (its CMU rig, scenes 60-91).
    #[arg(long)]
    pub camera: Option<String>,

    /// Explicit intrinsics "fx,fy,cx,cy" in pixels (overrides the preset's).
    #[arg(
        long,
        allow_negative_numbers = true,
        value_name = "FX,FY,CX,CY",
        value_delimiter = ','
    )]
    pub camera_k: Option<Vec<f64>>,

    /// Image width and height in pixels. Alone it scales the camera's intrinsics (the preset's,
    /// or the scene file's [camera] K: the same camera at another resolution); with --camera-k,
    /// K is used as given.
    #[arg(long, value_name = "W,H", value_delimiter = ',')]
    pub image_size: Option<Vec<u32>>,

    /// Camera distance from the look-at point, metres, as MIN..MAX.
    #[arg(long, allow_hyphen_values = true, value_name = "MIN..MAX", value_parser = parse_range)]
    pub distance_m: Option<[f64; 2]>,

    /// Camera elevation above the ground plane, degrees, as MIN..MAX.
    #[arg(long, allow_hyphen_values = true, value_name = "MIN..MAX", value_parser = parse_range)]
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

    /// BOP split folder name (default: train_pbr; with --replay each source frame's split,
    /// e.g. test).
    #[arg(long)]
    pub split: Option<String>,

    /// Frames per scene folder (BOP PBR sets use 1000).
    #[arg(long, default_value_t = 1000, value_parser = clap::value_parser!(u32).range(1..=1_000_000))]
    pub chunk_size: u32,

    /// RGB image format.
    #[arg(long, value_enum, default_value_t = RgbFormat::Png)]
    pub rgb_format: RgbFormat,

    /// JPEG quality for `--rgb-format jpg`.
    #[arg(long, default_value_t = 95, value_parser = clap::value_parser!(u8).range(1..=100))]
    pub jpg_quality: u8,

    /// Depth PNG unit in millimetres: stored value = depth_mm / depth_scale. 0.1 (BlenderProc's
    /// PBR sets; the default for --format bop and ycbv, where it is factor_depth 10000)
    /// reaches 6.5 m; 1.0 (the default for --format linemod) reaches 65 m.
    #[arg(long, allow_negative_numbers = true)]
    pub depth_scale: Option<f64>,

    /// Dataset layout to write.
    #[arg(long, value_enum, default_value_t = FormatArg::Bop)]
    pub format: FormatArg,

    /// --format linemod: an object gets a folder entry for a frame when its visib_fract is at
    /// least this.
    #[arg(long, allow_negative_numbers = true, default_value_t = 0.1)]
    pub min_visib_fract: f64,

    /// Visibility tolerance in metres for mask_visib (bop_toolkit's delta).
    #[arg(long, allow_negative_numbers = true, default_value_t = 0.015)]
    pub visib_delta_m: f64,

    /// Worker threads (default: all cores).
    #[arg(long, short, value_parser = crate::cli::threads())]
    pub jobs: Option<usize>,

    /// Stop at the first frame that fails instead of reporting failures at the end.
    #[arg(long)]
    pub fail_fast: bool,

    /// The share of the frames that may fail (each reported, the others written) before the
    /// run exits with 1. Frames whose objects do not fit are drawn again and then placed with
    /// fewer objects first, so a failure is rare. 0: any failure is an error.
    #[arg(long, value_name = "FRACTION", default_value_t = 0.01)]
    pub max_failed_fraction: f64,

    /// --backend blender: Cycles path-tracing samples per pixel.
    #[arg(long, default_value_t = 16, value_parser = clap::value_parser!(u32).range(1..=65_536))]
    pub samples: u32,

    /// --backend blender: denoise with OpenImageDenoise.
    #[arg(long)]
    pub denoise: bool,

    /// --backend blender: CPU threads for Cycles (default: all cores).
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u32).range(1..=1024))]
    pub blender_threads: Option<u32>,

    /// --backend blender: the venv with bpy (default: $SYNTHGEN_BLENDER_VENV, else
    /// ~/.cache/synthgen/blender-venv, which scripts/setup-blender.sh creates).
    #[arg(long, value_name = "DIR")]
    pub blender_venv: Option<PathBuf>,

    /// Render only shard I of N of the --frames (a contiguous slice; frame, scene and image
    /// ids stay global). Combine the shard folders with `synthgen merge`. BOP only.
    #[arg(long, value_name = "I/N")]
    pub shard: Option<Shard>,

    /// Finish an interrupted run in --out (a render or a --replay): frames already written
    /// are kept, the rest are rendered. Pass the same options as the interrupted run. BOP
    /// only.
    #[arg(long)]
    pub resume: bool,
}

impl RenderArgs {
    /// The split folder of a sampled render: `--split`, else train_pbr.
    pub fn split_name(&self) -> &str {
        self.split.as_deref().unwrap_or("train_pbr")
    }
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
