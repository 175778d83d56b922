//! Arguments of `synthgen experiment sim2real`.

use std::path::PathBuf;

use clap::{Args, ValueEnum};

use synthgen_core::scene::UpAxis;

use super::train::VisibleBoxArg;
use super::ModelArg;

fn parse_up(s: &str) -> Result<UpAxis, String> {
    UpAxis::ALL
        .into_iter()
        .chain([UpAxis::Any, UpAxis::Stable])
        .find(|a| a.as_str() == s)
        .ok_or_else(|| format!("{s:?}: one of +x, -x, +y, -y, +z, -z, any, stable"))
}

/// `experiment sim2real --model`: the depth models, and the RGB models (no depth at test).
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum Sim2realModelArg {
    /// Object centre from the masked depth points (PointNet offsets).
    Tnet,
    /// Rotation from colour + points (DenseFusion style), quaternion loss.
    Rnet,
    /// Both heads, per-pixel ADD loss (min over the object's symmetries).
    Full,
    /// RGB only: a whole pose from a box's colour crop (centre + Tz and a quaternion).
    Rgb,
    /// RGB only: per cell of a box's colour crop the object coordinates, the pose by PnP +
    /// RANSAC or the rotation head, centre + Tz.
    RgbDense,
}

impl Sim2realModelArg {
    /// The depth model, or None for the RGB models.
    pub fn depth_model(self) -> Option<ModelArg> {
        match self {
            Sim2realModelArg::Tnet => Some(ModelArg::Tnet),
            Sim2realModelArg::Rnet => Some(ModelArg::Rnet),
            Sim2realModelArg::Full => Some(ModelArg::Full),
            Sim2realModelArg::Rgb | Sim2realModelArg::RgbDense => None,
        }
    }
}

/// `experiment sim2real --refine`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum RefineArg {
    /// The network's pose as it is.
    None,
    /// ICP of the object's model on the instance's real depth points, from the network's
    /// centre (starts from a spread of rotations, and the network's rotation where it gives
    /// one; a fit that moves the centre more than 3 cm or explains under half of the points is
    /// refused).
    Icp,
    /// The RGB models (--model rgb, rgb-dense): each estimate's model contour moved onto the
    /// edges of its real RGB image (a refinement that matches too little of the contour is
    /// refused).
    Edges,
    /// The RGB models: a search over each object's rotations about the estimate's position
    /// first (its contour from 300 directions, 24 turns each, scored on the image's edges),
    /// the best sixteen and the estimate then refined as with edges, with the model's colours
    /// where it has them (edges inside the outline, colours deciding near-equal fits).
    Views,
}

pub const SIM2REAL_EXAMPLES: &str = "Examples:
  # Fit the scene and the sensor to real frames, render, train on synthetic only, test on
  # other real frames (their real depth and visible masks):
  synthgen experiment sim2real --fit ../shared/data/ycbv_real --test data/ycbv_test --out runs/s2r

  # One real dataset: the test scenes are held out of the fits (and of the real-only baseline):
  synthgen experiment sim2real --fit ../shared/data/ycbv_real --test ../shared/data/ycbv_real \\
      --test-scenes 2 --out runs/s2r_2

  # Also the ablation rows (no scene fit, distractors, textured surfaces, physics):
  synthgen experiment sim2real --fit REAL --test REAL --test-scenes 2 --ablation --out runs/s2r

  # The RGB models on RGB-only real photographs (Linemod-Occluded: one real scene, so the
  # scene comes from a scene file), scored with the GT boxes; rows realistic / plain raster,
  # Cycles at --cycles-frames, the naive box baseline:
  synthgen experiment sim2real --model rgb-dense --scene scenes/linemod_rgb.toml \\
      --test ../shared/data/lmo --out runs/s2r_lmo
  # ... each trained row's estimates refined on the photographs, kept to the GT visible boxes:
  synthgen experiment sim2real --model rgb-dense --scene scenes/linemod_rgb.toml \\
      --test ../shared/data/lmo --refine views --visible-box gt --out runs/s2r_lmo_views

  # YCB-Video with the textured scans (`synthgen model align --scans ... --out models_tex`):
  synthgen experiment sim2real --model rgb-dense --fit REAL --test REAL --test-scenes 2 \\
      --models models_tex --out runs/s2r_ycbv

  # The whole pipeline on tiny settings (quarter resolution, few frames and epochs):
  synthgen experiment sim2real --fit REAL --test REAL --test-scenes 2 --quick --out /tmp/s2r

Steps (each kept on a re-run with the same options; an interrupted one is redone):
  fit/        scene.toml (`synthgen scene fit` of the --fit frames), sensor.toml
              (`synthgen sensor fit`), their reports
  sources/    synthetic sets of the test objects: the fitted scene with the fitted sensor,
              with no sensor model, with the D455 model (+ the ablation variants)
  rows/NAME/  a model trained on one set (all test objects in one model), row.json with its
              errors on the real test frames, overall and per object
  detector/   a detector (boxes + instance masks) trained on the main row's set (--detector);
              detections.json its detections on the test frames (BOP format, no GT read),
              detection_scores.json their bop_toolkit COCO scores over the test scenes'
              images (detection_targets.json), detection_pictures/ a few of them drawn;
              rows/<main row>/no_gt.json the main row's model from these detections
Rows of the report: the fitted synthetic set (the result), no sensor, D455, the naive
baseline (the centre = the mean of the masked real depth points: no training), a model
trained on real frames only (the --fit frames outside the test scenes, as many steps as
the synthetic rows), and with --ablation one row per knob.

Output (in --out): report.md (printed), report.json ({\"all\", \"objects\", \"scenes\",
\"baselines\"}: centre errors; for rows with a rotation (full, rnet, TNet with --refine icp)
also BOP's \"ar\" (VSD on the real depth, MSSD, MSPD), \"add_s_auc\" (up to 10 cm, %),
\"acc_add\", 5cm5° and median errors), plot.png (mean centre error per row),
experiment.json (the settings). The RGB models:
report.json ({\"all\", \"objects\", \"scenes\", \"rows\"}: AR_MSPD, AR_MSSD, 5cm5°, ADD(-S),
medians; the main row is synth_realistic), rows/NAME/results.csv (BOP results format).
Both add \"detection\" (bbox/segm AP, AP50 per object) and \"no_gt\" (the main row's scores
with no GT box or mask anywhere at test time: crops or points from the detections).";

#[derive(Debug, Args)]
pub struct ExperimentSim2realArgs {
    /// Real frames with GT poses and depth (YCB-Video, BOP or Linemod) to fit the scene
    /// (camera, views, objects' rest poses, objects per frame) and the depth sensor to. The
    /// RGB models need no depth here (the table plane from the objects' rest poses, no sensor
    /// fit), and may take --scene instead.
    #[arg(long, value_name = "DIR", required_unless_present = "scene")]
    pub fit: Option<PathBuf>,

    /// Real frames to test on: their objects (those with a model) are rendered and scored.
    /// May be --fit itself, with --test-scenes held out of the fits.
    #[arg(long, value_name = "DIR")]
    pub test: PathBuf,

    /// Only these scene ids of --test are tested on (required when --test is --fit: they are
    /// then left out of the scene and sensor fits and of the real-only baseline).
    #[arg(long, value_delimiter = ',', value_name = "ID,...")]
    pub test_scenes: Vec<u32>,

    #[arg(long, value_enum, default_value_t = Sim2realModelArg::Tnet)]
    pub model: Sim2realModelArg,

    /// Synthetic frames per rendered set. [default: 1500; 48 with --quick]
    #[arg(long)]
    pub frames: Option<usize>,

    /// RGB models: a scene file to render the synthetic sets with instead of a scene fitted to
    /// --fit (e.g. scenes/linemod_rgb.toml for Linemod-Occluded, one real scene with no other
    /// to fit to). Its objects are replaced by the test objects.
    #[arg(long, value_name = "FILE")]
    pub scene: Option<PathBuf>,

    /// Render each test object from the one mesh in DIR/<its name>/ (e.g. the textured scans
    /// aligned by `synthgen model align --scans`) instead of the dataset's model, in every
    /// synthetic set (the detector trained here learns their colours); objects without a
    /// folder keep the dataset's. RGB models with --refine views: the refinement compares
    /// the real images with these meshes' colours too.
    #[arg(long, value_name = "DIR")]
    pub models: Option<PathBuf>,

    /// RGB models: frames of the Cycles row (the Blender backend, 16 samples) and of the plain
    /// and realistic raster rows at the same count; 0: no such rows. Cycles renders ~5-15 s a
    /// frame on 2 cores. [default: 200; 4 with --quick]
    #[arg(long, value_name = "N")]
    pub cycles_frames: Option<usize>,

    #[command(flatten)]
    pub budget: super::budget::TrainBudgetArgs,

    /// Also the ablation rows: the fitted set without the scene fit (synthgen's default
    /// scene, all objects standing on +z), with primitive distractors, with textured
    /// ground and walls, with physics placement, with unseen objects on +z; and
    /// synth_fitted's frames trained without the mask jitter, with shifted masks, with
    /// occlusion cuts, with point dropout, with the other --per-object choice.
    #[arg(long)]
    pub ablation: bool,

    /// How test objects that no --fit frame shows stand in the synthetic sets: a model axis
    /// up (+x, -x, +y, -y, +z, -z), `any` (each instance on one of the six, drawn uniformly),
    /// or `stable` (each instance on a stable face of the mesh's convex hull, drawn with the
    /// probability that a drop ends there). Objects the fit frames show get their fitted rest
    /// pose.
    #[arg(long, value_name = "AXIS", default_value = "stable", value_parser = parse_up, allow_hyphen_values = true)]
    pub unseen_up: UpAxis,

    /// Training on the synthetic sets: each instance's visible mask grows or shrinks by up
    /// to this many pixels (a real segmenter's boundary). 0: as rendered. The default was
    /// chosen on validation scenes (docs/experiments.md).
    #[arg(long, value_name = "PX", default_value_t = 3, value_parser = clap::value_parser!(u32).range(0..=64))]
    pub mask_jitter_px: u32,

    /// Training on the synthetic sets: each instance's visible mask moves by up to this many
    /// pixels along x and y (a mask registered to the colour image over a depth image a few
    /// pixels off). 0: in place.
    #[arg(long, value_name = "PX", default_value_t = 0, value_parser = clap::value_parser!(u32).range(0..=64))]
    pub mask_shift_px: u32,

    /// Training on the synthetic sets: the probability that an instance loses the pixels
    /// beyond a random line (10-50 % of them: occluders the renders lack).
    #[arg(long, value_name = "P", default_value_t = 0.0)]
    pub occlusion_prob: f64,

    /// Training on the synthetic sets: up to this share of each instance's pixels is
    /// dropped at random.
    #[arg(long, value_name = "P", default_value_t = 0.0)]
    pub point_dropout: f64,

    /// TNet conditioned on the object class (a learned vector per object in its global
    /// feature): where the centre lies behind the visible surface depends on the object.
    #[arg(long)]
    pub per_object: bool,

    /// TNets trained per row (on the same frames, each from its own training seed), their
    /// centres averaged: less of the training's seed-to-seed spread. 1: one model. The
    /// default was chosen on validation scenes (docs/experiments.md). [default: 3; 1 with
    /// --quick]
    #[arg(long, value_name = "K", value_parser = parse_ensemble)]
    pub ensemble: Option<usize>,

    /// How the depth models' poses are finished on the real depth: `icp` fits each object's
    /// model to the instance's depth points (as PoseCNN and DenseFusion finish theirs) — from
    /// TNet's centre, the fit then giving the rotation TNet lacks; from Full's whole pose, its
    /// rotation one more start and the judge between fits the depth cannot tell apart — and
    /// `none` keeps the network's. With `icp` each trained row also reports its scores before
    /// the refinement, and the row naive_icp (the same ICP from the naive centroid) shows what
    /// the network adds; --model rnet (no centre) keeps its poses. Changing it on a finished
    /// experiment scores its trained rows again without training them. The RGB models
    /// (--model rgb|rgb-dense) take `edges` or `views`: each trained row's estimates refined on
    /// the real RGB images (the contour onto the image's edges; `views` searches the rotations
    /// first), with its scores before the refinement beside them; with `icp` (the default)
    /// they keep theirs.
    #[arg(long, value_enum, default_value_t = RefineArg::Icp)]
    pub refine: RefineArg,

    /// The RGB models with --refine edges|views: what of each test instance shows, which the
    /// refinement keeps to, as `eval --visible-box`. `gt`: its GT visible box (the box the
    /// crops already come from), so no edge outside it is the object's and an outline short
    /// of it pays for the gap. Default: none.
    #[arg(long, value_enum, default_value_t = VisibleBoxArg::None)]
    pub visible_box: VisibleBoxArg,

    /// Seeds the renders and the training.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,

    /// Only these rows (synth_fitted, synth_no_sensor, synth_d455, the ablation rows,
    /// real_only; the naive centroid always): a quicker look, or a comparison of settings.
    /// Rows missing from an earlier run are computed on a re-run. Default: all.
    #[arg(long, value_delimiter = ',', value_name = "ROW,...")]
    pub rows: Vec<String>,

    /// The share of a synthetic set's frames that may fail to render (each reported and
    /// left out) before the experiment stops. Frames whose objects do not fit are drawn
    /// again and then placed with fewer objects first.
    #[arg(long, value_name = "FRACTION", default_value_t = 0.01)]
    pub max_failed_fraction: f64,

    /// The detector of the scores from raw frames (report.json's "no_gt" and "detection"):
    /// `train` (one trained on the main row's synthetic frames, into OUT/detector), a folder
    /// `synthgen detector train --out` wrote, or `none` (no scores from raw frames). Its
    /// detections on the test frames go to OUT/detections.json (BOP's detections format).
    #[arg(long, value_name = "train|none|DIR", default_value = "train")]
    pub detector: String,

    /// Epochs of the detector trained here. [default: 30; 2 with --quick]
    #[arg(long, value_name = "N", value_parser = clap::builder::RangedU64ValueParser::<usize>::new().range(1..=10000))]
    pub detector_epochs: Option<usize>,

    /// Small and fast, to check the pipeline: the --quick defaults above, synthetic sets at a
    /// quarter of the camera's resolution.
    #[arg(long)]
    pub quick: bool,

    /// Output folder.
    #[arg(long, default_value = "runs/sim2real")]
    pub out: PathBuf,

    /// Start over in a non-empty --out that holds an experiment with other settings.
    #[arg(long)]
    pub force: bool,

    /// Worker threads (default: all cores).
    #[arg(long, short = 'j', value_parser = crate::cli::threads())]
    pub jobs: Option<usize>,
}

/// `--ensemble`: 1..=16 models.
fn parse_ensemble(v: &str) -> Result<usize, String> {
    match v.parse::<usize>() {
        Ok(k) if (1..=16).contains(&k) => Ok(k),
        _ => Err(format!("expected 1 to 16 models, got {v:?}")),
    }
}
