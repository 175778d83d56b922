//! Arguments of `synthgen train` and `synthgen eval`.

use std::path::PathBuf;

use clap::{Args, ValueEnum};

#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum ModelArg {
    /// Object centre from the masked depth points (PointNet offsets).
    Tnet,
    /// Rotation from colour + points (DenseFusion style), quaternion loss.
    Rnet,
    /// Both heads, per-pixel ADD loss (min over the object's symmetries).
    Full,
}

/// `synthgen train --model`: the RGB-D models of the experiments, and the RGB model.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum TrainModelArg {
    /// Object centre from the masked depth points (PointNet offsets).
    Tnet,
    /// Rotation from colour + points (DenseFusion style), quaternion loss.
    Rnet,
    /// Both heads, per-pixel ADD loss (min over the object's symmetries).
    Full,
    /// A whole pose from the colour crop of a box, no depth: Tz and the centre inside the
    /// box, or XYZ directly (--translation), and a quaternion.
    Rgb,
    /// Per pixel of a box's colour crop the visibility and the 3D object coordinates, then
    /// the pose by PnP + RANSAC; no depth (trains on frames with depth: the targets).
    RgbDense,
}

/// How the RGB model regresses the translation.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum TranslationArg {
    /// The centre's offset inside the box and the depth Tz; Tx, Ty through the intrinsics.
    CentreTz,
    /// (Tx, Ty, Tz) directly.
    Xyz,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum ScheduleArg {
    /// Cosine decay from --lr to --lr/100 over all steps.
    Cosine,
    /// --lr, then --lr/10 for the last third of the epochs.
    Step,
    Constant,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum DeviceArg {
    Cpu,
    /// The first CUDA GPU; needs the `cuda` cargo feature.
    Cuda,
}

/// Which rotation matrices `eval` scores (synthgen_train::metrics::Rotations).
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum RotationsArg {
    /// The matrices as the files store them, GT and estimates: bop_toolkit's pose_error,
    /// PoseCNN's and DenseFusion's evaluations (published numbers).
    AsStored,
    /// The nearest proper rotation of each (real annotations are only nearly orthonormal).
    Nearest,
}

impl From<RotationsArg> for synthgen_train::metrics::Rotations {
    fn from(r: RotationsArg) -> Self {
        match r {
            RotationsArg::AsStored => Self::AsStored,
            RotationsArg::Nearest => Self::Nearest,
        }
    }
}

/// `eval --visible-box` (synthgen_jobs::rgb_refine::VisibleBoxes).
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum VisibleBoxArg {
    /// The whole contour counts wherever it falls.
    None,
    /// Each instance's GT visible box (bbox_visib, else its visible mask's box): what a
    /// checkpoint's crops come from; the numbers are then numbers with GT boxes.
    Gt,
    /// The --detections box of the estimate's object nearest it (a detector's): no GT box.
    Detected,
}

impl From<VisibleBoxArg> for synthgen_jobs::rgb_refine::VisibleBoxes {
    fn from(b: VisibleBoxArg) -> Self {
        match b {
            VisibleBoxArg::None => Self::None,
            VisibleBoxArg::Gt => Self::Gt,
            VisibleBoxArg::Detected => Self::Detected,
        }
    }
}

pub const TRAIN_EXAMPLES: &str = "Examples:
  # Render 2000 driller frames, train TNet on them (10% of the frames held out):
  synthgen render --objects obj_000008.ply --frames 2000 --seed 1 --out data/drill
  synthgen train --data data/drill --model tnet --epochs 30 --out runs/tnet

  # Go on from the last checkpoint up to 50 epochs:
  synthgen train --data data/drill --out runs/tnet --epochs 50 --resume

  # The full model (translation + rotation), starting from the TNet run:
  synthgen train --data data/drill --model full --init runs/tnet/model.safetensors --out runs/full

  # The RGB model (no depth): a pose from the crop of each object's box (the GT
  # bbox_visib, jittered while training), centre + Tz or direct XYZ:
  synthgen train --data data/lm --model rgb --translation centre-tz --epochs 20 --out runs/rgb

  # The dense RGB model (per pixel the object's 3D coordinates, then PnP), and a box
  # detector so that it runs without GT boxes on the real LM-O photographs:
  synthgen train --data data/lmo_synth --model rgb-dense --epochs 20 --lr 2e-3 --out runs/dense
  synthgen detector train --data data/lmo_clutter --out runs/det
  synthgen detector run --checkpoint runs/det --data ../shared/data/lmo --out det.json
  synthgen eval --checkpoint runs/dense/model.safetensors --data ../shared/data/lmo \\
      --detections det.json --bop

  # Render, train on synthetic frames only and score on real frames, in one command:
  synthgen experiment sim2real --model rgb-dense --scene scenes/linemod_rgb.toml \\
      --test ../shared/data/lmo --out runs/s2r_lmo

Output (in --out):
  model.safetensors   the weights after the last finished epoch
  config.json         model, width, points, normalization, data, seed, ...
  state.json          epochs and steps done (for --resume)
  metrics.jsonl       one JSON line per epoch: epoch, train_loss, val_loss,
                      val_centre_error_m, val_add_s_acc and val_mean_re_deg
                      (rnet, full, rgb), val_acc_5cm5deg (rgb), lr, seconds
  curve.png           losses (top) and validation centre error or ADD(-S) error
                      rate (bottom), log scales";

#[derive(Debug, Args)]
pub struct TrainArgs {
    /// The dataset to train on: BOP, or Linemod (data/NN/gt.yml; detected).
    #[arg(long, value_name = "DIR")]
    pub data: PathBuf,

    /// The split folder to read (default: `test` if present, else the only split).
    #[arg(long)]
    pub split: Option<String>,

    #[arg(long, value_enum, default_value_t = TrainModelArg::Tnet)]
    pub model: TrainModelArg,

    /// The rgb model's translation: centre + Tz (the seed's) or direct XYZ.
    #[arg(long, value_enum, default_value_t = TranslationArg::CentreTz)]
    pub translation: TranslationArg,

    /// TNet: condition on the object class (a learned vector per object of the training
    /// data; objects it lacks are predicted without one). `eval` reads the classes from the
    /// run's config.json.
    #[arg(long)]
    pub per_object: bool,

    #[arg(long, default_value_t = 30)]
    pub epochs: usize,

    /// Instances per step.
    #[arg(long, default_value_t = 32)]
    pub batch: usize,

    /// Peak learning rate (AdamW).
    #[arg(long, allow_negative_numbers = true, default_value_t = 1e-3)]
    pub lr: f64,

    #[arg(long, allow_negative_numbers = true, default_value_t = 1e-4)]
    pub weight_decay: f64,

    #[arg(long, value_enum, default_value_t = ScheduleArg::Cosine)]
    pub schedule: ScheduleArg,

    /// Seeds point sampling, the train/val split, initialization order and shuffling.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,

    /// Points sampled per object instance.
    #[arg(long, default_value_t = 500)]
    pub points: usize,

    /// Width of the global feature.
    #[arg(long, default_value_t = 128)]
    pub width: usize,

    /// Side of the RGB crop around the object, pixels: rnet and full (even; default 48),
    /// rgb (at least 16; default 64).
    #[arg(long)]
    pub crop_size: Option<u32>,

    /// Model points per object in the full model's ADD loss.
    #[arg(long, default_value_t = 100)]
    pub loss_points: usize,

    /// Full: train with the plain ADD loss even for objects with symmetries in models_info
    /// (an ablation; eval still scores them with ADD-S).
    #[arg(long)]
    pub no_symmetric_loss: bool,

    /// Initialize the variables this checkpoint shares with the model (same names and
    /// shapes), e.g. a TNet or RNet run's model.safetensors for --model full. Repeatable.
    #[arg(long, value_name = "CKPT")]
    pub init: Vec<PathBuf>,

    /// Fraction of frames held out for validation.
    #[arg(long, allow_negative_numbers = true, default_value_t = 0.1)]
    pub val_fraction: f64,

    /// Leave out instances less visible than this.
    #[arg(long, allow_negative_numbers = true, default_value_t = 0.1)]
    pub min_visib_fract: f64,

    /// The run folder.
    #[arg(long, default_value = "runs/tnet")]
    pub out: PathBuf,

    /// Continue the run in --out from its last checkpoint (AdamW's moments restart), as it
    /// was configured: --epochs may be raised; a setting that makes the run (--lr, --batch,
    /// --model, ...) given with another value than the run's is refused.
    #[arg(long)]
    pub resume: bool,

    /// Overwrite a run folder that already has a checkpoint.
    #[arg(long)]
    pub force: bool,

    #[arg(long, value_enum, default_value_t = DeviceArg::Cpu)]
    pub device: DeviceArg,

    /// Worker threads (default: all cores).
    #[arg(long, short = 'j', value_parser = crate::cli::threads())]
    pub jobs: Option<usize>,
}

pub const EVAL_EXAMPLES: &str = "Examples:
  # Score a BOP results CSV against a dataset's ground truth:
  synthgen eval --results results.csv --data data/lmo --split test --json scores.json

  # The BOP challenge's Average Recall (VSD, MSSD, MSPD) as bop_toolkit computes it,
  # next to ADD(-S); test_targets_bop19.json in --data is used when present:
  synthgen eval --results results.csv --data data/lmo --bop --json scores.json

  # Centre error of a trained TNet on a dataset:
  synthgen eval --checkpoint runs/tnet/model.safetensors --data data/drill_test

  # ADD(-S), 5cm5°, E_te, E_re of a full (or rnet, or rgb) model, as a table and JSON:
  synthgen eval --checkpoint runs/full/model.safetensors --data data/drill_test --json s.json

  # Spread of the estimates over repeated frames of a static object:
  synthgen eval --checkpoint runs/full/model.safetensors --data data/static --stability

Results CSV (bop_toolkit): scene_id,im_id,obj_id,score,R,t,time with R 9 values
row-major and t in millimetres, space-separated. Accuracy is over all GT instances
(an instance without an estimate counts as wrong); the highest-scoring estimate
per (image, object) counts; ADD-S is used for objects with symmetries in
models_info.json. An rnet checkpoint predicts rotation only: its poses take the
GT translation (E_te = 0). An rgb or rgb-dense checkpoint reads no depth: it sees
the crop of each instance's GT visible box, or with --detections of a detector's box
(`synthgen detector run`; an instance without one counts as a miss). See
docs/metrics.md.

  # The dense RGB model from a detector's boxes, refined on the RGB images:
  synthgen eval --checkpoint runs/dense/model.safetensors --data ../shared/data/lmo \\
      --detections det.json --refine views --visible-box detected --bop

The RGB model's centre + Tz against direct XYZ (5cm5°, per object):
  synthgen experiment rgb --train data/synth --test data/test --out runs/rgb

A Linemod --data is read with the scene and image ids that `synthgen convert --to bop`
gives its frames (docs/training.md); a results CSV for it uses those ids.";

/// `eval --refine`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum RgbRefineArg {
    /// The estimates as they are.
    None,
    /// Contours onto the RGB image's edges.
    Edges,
    /// A search over the object's rotations about the estimate's position first (its contour
    /// from 300 directions, 24 turns each, scored on the image's edges); the best sixteen and
    /// the estimate then refined as with edges, and where the dataset's models have colours,
    /// with the edges inside the outline too and the colours deciding between near-equal fits;
    /// the winner then turned a few degrees out of the image plane and refined again
    /// (--restart-deg) (slower: ~0.5 s an estimate on 2 cores).
    Views,
}

impl RgbRefineArg {
    /// The name `synthgen_jobs::rgb_refine::refine_options` reads.
    pub fn name(self) -> &'static str {
        match self {
            RgbRefineArg::None => "none",
            RgbRefineArg::Edges => "edges",
            RgbRefineArg::Views => "views",
        }
    }
}

#[derive(Debug, Args)]
pub struct EvalArgs {
    /// The dataset with the ground truth (and models/ for ADD): BOP, or Linemod (detected).
    #[arg(long, value_name = "DIR")]
    pub data: PathBuf,

    /// A BOP results CSV to score.
    #[arg(
        long,
        value_name = "CSV",
        conflicts_with = "checkpoint",
        required_unless_present = "checkpoint"
    )]
    pub results: Option<PathBuf>,

    /// A trained model (its config.json beside it) to run on --data.
    #[arg(long, value_name = "FILE")]
    pub checkpoint: Option<PathBuf>,

    /// The split folder (default: `test` if present, else the only split).
    #[arg(long)]
    pub split: Option<String>,

    /// GT instances less visible than this are not scored (BOP uses 0.1).
    #[arg(long, allow_negative_numbers = true, default_value_t = 0.1)]
    pub min_visib_fract: f64,

    /// Also write the scores as JSON.
    #[arg(long, value_name = "PATH")]
    pub json: Option<PathBuf>,

    /// Seed for point sampling with --checkpoint.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,

    /// With --checkpoint of a full or rgb model, also write its estimates as a BOP results CSV
    /// (for bop_toolkit, `synthgen view --results`, or a later `eval --results`); with
    /// --results and --refine, the refined estimates.
    #[arg(long, value_name = "CSV")]
    pub save_results: Option<PathBuf>,

    /// Refine the estimates before scoring: `edges` moves each estimate's model contour onto
    /// the edges of its RGB image (directional chamfer matching; no depth, nothing learned);
    /// `views` first searches the object's rotations on those edges, for estimates far off.
    /// For the results CSV's estimates, or an rgb / rgb-dense checkpoint's. See
    /// docs/metrics.md.
    #[arg(long, value_enum, default_value_t = RgbRefineArg::None)]
    pub refine: RgbRefineArg,

    /// With --refine views: compare the image with these meshes' colours instead of the
    /// dataset's models' (YCB-Video's own models carry no texture): a folder with one
    /// subfolder per object, in the dataset's frame, as `synthgen model align --scans
    /// ../shared/data/ycb_textured --to-dataset DIR --out models_tex` writes. The contour and
    /// the scores still use the dataset's models.
    #[arg(long, value_name = "DIR")]
    pub refine_models: Option<PathBuf>,

    /// With --refine views: how many of the view search's best poses are refined (more: a
    /// little more often the right one among them, and proportionally slower; see
    /// docs/experiments.md for 16 against 40). Default: 16.
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u32).range(1..=200))]
    pub view_candidates: Option<u32>,

    /// With --refine views: how much the colour regions either side of the outline weigh
    /// beside its edges, pixels of edge cost per nat (the pixels just inside the outline should
    /// look like the object, those just outside like its surroundings; docs/metrics.md).
    /// Default: 3; 0: the edges alone, as before 2026-12-05.
    #[arg(long, value_name = "PX", value_parser = parse_region_weight, allow_hyphen_values = true)]
    pub region_weight: Option<f64>,

    /// With --refine views: how much the model's own colours weigh beside the edges, pixels
    /// of edge cost per unit of photometric disagreement (1 minus the correlation of the
    /// model's colours at 300 points of its visible surface with the image's under them): the
    /// texture inside the outline pins the turns the outline hardly shows. Needs coloured
    /// models (vertex colours or a texture; --refine-models); the view search's best 64 poses
    /// are also ranked again with it before the best 16 are refined. Default: 3; 0: neither,
    /// as before 2026-12-06.
    #[arg(long, value_name = "PX", value_parser = parse_photometric_weight, allow_hyphen_values = true)]
    pub photometric_weight: Option<f64>,

    /// With --refine views: the winning end turned by this many degrees each way about the
    /// image's two axes (turns out of the image plane, which the outline shows least) and
    /// refined again from each, the cheapest kept, twice at most: an end a few degrees off
    /// the right view is finished. Default: 6; 0: no restarts, as before 2026-12-06.
    #[arg(long, value_name = "DEG", value_parser = parse_restart_deg, allow_hyphen_values = true)]
    pub restart_deg: Option<f64>,

    /// With --refine: what of each instance shows, which the refinement then keeps to: no
    /// edge outside the box (widened by 4 px) is the object's, so a contour point there costs
    /// as on a bare background however near an occluder's edge it falls, and an outline that
    /// does not reach each side of the box pays for the gap (--box-gap-weight). `gt`: the GT
    /// visible box (BOP's bbox_visib), the box a checkpoint's crops come from; numbers made
    /// with it are numbers with GT boxes (LM-O: docs/experiments.md). `detected`: the box of
    /// --detections nearest the estimate. Default: none.
    #[arg(long, value_enum, default_value_t = VisibleBoxArg::None)]
    pub visible_box: VisibleBoxArg,

    /// A detections file (BOP's format, as `synthgen detector run` writes it): an RGB
    /// checkpoint's crops come from its boxes instead of the GT boxes, a depth checkpoint's
    /// (tnet, rnet, full) points from its masks ("segmentation") instead of the GT masks (per
    /// image and object, the best as many as the object has GT instances; an instance
    /// without one gets no estimate and counts as a miss), and --visible-box detected reads
    /// the boxes.
    #[arg(long, value_name = "FILE")]
    pub detections: Option<PathBuf>,

    /// A detector (`synthgen detector train` run folder): the checkpoint (full, rgb,
    /// rgb-dense) runs as `synthgen predict` runs it on the dataset's frames — the detector
    /// on each raw frame, no GT box or mask read, --refine inside — and its whole poses are
    /// scored: what a robot gets. --save-results writes them.
    #[arg(
        long,
        value_name = "DIR",
        requires = "checkpoint",
        conflicts_with = "detections"
    )]
    pub detector: Option<PathBuf>,

    /// With --visible-box: what each pixel by which the box reaches beyond the outline costs,
    /// summed over its four sides, pixels of edge cost per pixel of gap. Default: 0.1; 0: the
    /// box only hides the edges outside it.
    #[arg(long, value_name = "PX", value_parser = parse_box_gap_weight, allow_hyphen_values = true)]
    pub box_gap_weight: Option<f64>,

    /// Also score with BOP's Average Recall (AR = mean of AR_VSD, AR_MSSD, AR_MSPD), computed
    /// as bop_toolkit's eval_bop19_pose.py does; VSD renders each estimate and needs the test
    /// depth images (without them: MSSD and MSPD only). See docs/metrics.md.
    #[arg(long)]
    pub bop: bool,

    /// BOP targets (a test_targets_bop19.json: scene_id, im_id, obj_id, inst_count). Default:
    /// test_targets_bop19.json in --data when present, else every GT instance of the split.
    #[arg(long, value_name = "FILE", requires = "bop")]
    pub targets: Option<PathBuf>,

    /// With --bop, also write every scored estimate's MSSD (mm), MSPD (px) and VSD (per tau)
    /// against each GT instance of its object, as JSON (bop_toolkit's errors_*.json).
    #[arg(long, value_name = "PATH", requires = "bop")]
    pub bop_errors: Option<PathBuf>,

    /// bop_toolkit's visib_gt_min for --bop: GT instances less visible do not count. The
    /// default, -1, counts the inst_count most visible instances of each target, as BOP 2019.
    #[arg(long, requires = "bop", allow_negative_numbers = true, default_value_t = -1.0)]
    pub visib_gt_min: f64,

    /// Report the mean and covariance of the estimated translation and quaternion over
    /// groups of frames with the same GT pose (a static object seen repeatedly), per object.
    /// Needs --checkpoint of an rnet or full model (tnet: translation only).
    #[arg(long, requires = "checkpoint")]
    pub stability: bool,

    /// Which rotation matrices ADD(-S), the rotation error and 5cm5° use: the files' as stored
    /// (GT and estimates, as bop_toolkit's pose_error scores them) or the nearest proper
    /// rotation of each. --bop always scores the stored numbers, as bop_toolkit does.
    #[arg(long, value_enum, default_value_t = RotationsArg::AsStored)]
    pub rotations: RotationsArg,

    #[arg(long, value_enum, default_value_t = DeviceArg::Cpu)]
    pub device: DeviceArg,
}

/// `--photometric-weight`: a finite weight of 0 or more.
fn parse_photometric_weight(v: &str) -> Result<f64, String> {
    parse_weight(
        v,
        "pixels per unit of disagreement; 0: colours not compared",
    )
}

/// `--restart-deg`: degrees from 0 to 90.
fn parse_restart_deg(v: &str) -> Result<f64, String> {
    match v.parse::<f64>() {
        Ok(d) if (0.0..=90.0).contains(&d) => Ok(d),
        _ => Err(format!(
            "expected a turn of 0 to 90 degrees (0: no restarts), got {v:?}"
        )),
    }
}

/// `--box-gap-weight`: a finite weight of 0 or more.
fn parse_box_gap_weight(v: &str) -> Result<f64, String> {
    parse_weight(
        v,
        "pixels of edge cost per pixel of gap; 0: no cost for a gap",
    )
}

/// `--region-weight`: a finite weight of 0 or more.
fn parse_region_weight(v: &str) -> Result<f64, String> {
    parse_weight(v, "pixels per nat; 0: the edges alone")
}

/// A finite weight of 0 or more; `meaning` (its unit, what 0 does) in the refusal.
fn parse_weight(v: &str, meaning: &str) -> Result<f64, String> {
    match v.parse::<f64>() {
        Ok(w) if w.is_finite() && w >= 0.0 => Ok(w),
        _ => Err(format!(
            "expected a weight of 0 or more ({meaning}), got {v:?}"
        )),
    }
}
