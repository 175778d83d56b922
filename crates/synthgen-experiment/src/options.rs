//! What each experiment is asked to do: the options of `synthgen experiment mix`, `sim2real`
//! and `rgb` as plain data. The CLI maps its flags onto these; the Python package its keyword
//! arguments (as JSON: every field may be left out, unknown fields are refused). `Default`
//! gives the flags' defaults (required paths empty).

use std::path::PathBuf;

use serde::{Deserialize, Serialize};

use synthgen_core::scene::UpAxis;
use synthgen_curate::mix::SceneRef;
use synthgen_jobs::rgb_refine::VisibleBoxes;
use synthgen_train::models::rgb::Translation;

/// The depth models of the experiments (`--model`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Model {
    /// Object centre from the masked depth points (PointNet offsets).
    #[default]
    Tnet,
    /// Rotation from colour + points (DenseFusion style), quaternion loss.
    Rnet,
    /// Both heads, per-pixel ADD loss (min over the object's symmetries).
    Full,
}

impl Model {
    /// The model's name in files and commands (`tnet`, `rnet`, `full`).
    pub fn name(self) -> &'static str {
        match self {
            Model::Tnet => "tnet",
            Model::Rnet => "rnet",
            Model::Full => "full",
        }
    }
}

/// The models `experiment sim2real` trains: the depth models, or the RGB ones.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Sim2realModel {
    #[default]
    Tnet,
    Rnet,
    Full,
    /// The RGB model (quaternion and translation heads on a crop).
    Rgb,
    /// The correspondence-based RGB model (PnP + RANSAC).
    RgbDense,
}

impl Sim2realModel {
    /// The depth model, None for the RGB models.
    pub fn depth_model(self) -> Option<Model> {
        match self {
            Sim2realModel::Tnet => Some(Model::Tnet),
            Sim2realModel::Rnet => Some(Model::Rnet),
            Sim2realModel::Full => Some(Model::Full),
            Sim2realModel::Rgb | Sim2realModel::RgbDense => None,
        }
    }
}

/// Where `experiment sim2real` gets the detector whose boxes and masks the pose rows read
/// for the report's `no_gt` scores (`--detector`; JSON: `"train"`, `"none"` or a folder).
#[derive(Debug, Clone, PartialEq, Eq, Default, Deserialize)]
#[serde(from = "String")]
pub enum DetectorChoice {
    /// Trained on the experiment's own synthetic frames (its main set).
    #[default]
    Train,
    /// No detector: no `no_gt` scores.
    None,
    /// A trained detector's run folder (`synthgen detector train --out`).
    Run(PathBuf),
}

impl From<String> for DetectorChoice {
    fn from(s: String) -> DetectorChoice {
        match s.as_str() {
            "train" => DetectorChoice::Train,
            "none" => DetectorChoice::None,
            _ => DetectorChoice::Run(PathBuf::from(s)),
        }
    }
}

/// How `experiment sim2real` finishes a depth model's centre on the real depth.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Refine {
    /// The network's centre as it is.
    #[default]
    None,
    /// The object's model fitted to the instance's depth points by ICP from the network's
    /// centre (`synthgen_physics::refine`).
    Icp,
    /// The RGB models' poses: the object's contour moved onto the edges of the RGB image
    /// (`synthgen_fit::edge_refine`).
    Edges,
    /// The RGB models' poses: a search over each object's rotations about the estimate's
    /// position first, its best candidates and the estimate then refined as with `Edges`.
    Views,
}

/// The training budget of every trained row; None takes the default.
#[derive(Debug, Clone, Copy, PartialEq, Default, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct TrainBudgetOptions {
    /// Training epochs per trained row. [default: 8; 20 for the RGB models; 2 with quick]
    pub epochs: Option<usize>,
    /// Instances per step. [default: 32; 8 with quick]
    pub batch: Option<usize>,
    /// Peak learning rate (AdamW, cosine schedule). [default: 1e-3; 2e-3 for the RGB models]
    pub lr: Option<f64>,
    /// Points sampled per object instance. [default: 500; 64 with quick]
    pub points: Option<usize>,
    /// Width of the global feature. [default: 128; 16 with quick]
    pub width: Option<usize>,
}

/// [`TrainBudgetOptions`] with the defaults filled in.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TrainBudget {
    pub epochs: usize,
    pub batch: usize,
    pub lr: f64,
    pub points: usize,
    pub width: usize,
}

impl TrainBudgetOptions {
    /// The budget: the options, else the defaults (smaller with `quick`).
    pub fn resolve(&self, quick: bool) -> TrainBudget {
        let pick = |v: Option<usize>, small: usize, normal: usize| {
            v.unwrap_or(if quick { small } else { normal })
        };
        TrainBudget {
            epochs: pick(self.epochs, 2, 8),
            batch: pick(self.batch, 8, 32),
            lr: self.lr.unwrap_or(1e-3),
            points: pick(self.points, 64, 500),
            width: pick(self.width, 16, 128),
        }
    }

    /// The budget of the RGB models (`sim2real` with `rgb`/`rgb-dense`): the dense model's
    /// settings of docs/experiments.md (20 epochs, lr 2e-3).
    pub fn resolve_rgb(&self, quick: bool) -> TrainBudget {
        TrainBudget {
            epochs: self.epochs.unwrap_or(if quick { 2 } else { 20 }),
            lr: self.lr.unwrap_or(2e-3),
            ..self.resolve(quick)
        }
    }
}

impl TrainBudget {
    /// Whether every count is positive.
    pub fn is_positive(&self) -> bool {
        self.epochs > 0 && self.batch > 0 && self.points > 0 && self.width > 0
    }
}

/// `synthgen experiment mix`: the real/synthetic mixing table.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct MixOptions {
    /// The real dataset (BOP, Linemod or YCB-Video); None with `real_proxy`.
    pub real: Option<PathBuf>,
    /// A rendered stand-in for the real set.
    pub real_proxy: bool,
    /// The synthetic dataset; None: rendered here.
    pub synth: Option<PathBuf>,
    /// Scene spec of the rendered synthetic set.
    pub scene: Option<PathBuf>,
    /// Meshes of the rendered sets.
    pub objects: Vec<PathBuf>,
    /// BOP object ids of `objects`.
    pub obj_ids: Vec<u32>,
    pub model: Model,
    /// Training frames per fixed-total row. [default: 1500; 42 with quick]
    pub total: Option<usize>,
    /// Rows as `REAL/SYNTH` counts instead of the sixths of `total`.
    pub ratios: Vec<String>,
    /// Held-out real test frames. [default: total/5; 8 with quick]
    pub test_count: Option<usize>,
    /// The test split is every real frame of these scenes.
    pub test_scenes: Vec<SceneRef>,
    /// Rows "all the real training frames + K× as many synthetic".
    pub plus_synth: Vec<usize>,
    pub budget: TrainBudgetOptions,
    pub seed: u64,
    /// Training seeds per row.
    pub repeats: usize,
    /// Small and fast, to check the pipeline.
    pub quick: bool,
    pub out: PathBuf,
    /// Start over in an `out` holding other settings.
    pub force: bool,
    /// Worker threads (None: all cores).
    pub jobs: Option<usize>,
    /// The command that reproduces this run, recorded in the manifests (the CLI's argv; the
    /// Python package writes the equivalent `synthgen experiment mix ...`).
    pub command_line: Vec<String>,
}

impl Default for MixOptions {
    fn default() -> MixOptions {
        MixOptions {
            real: None,
            real_proxy: false,
            synth: None,
            scene: None,
            objects: Vec::new(),
            obj_ids: Vec::new(),
            model: Model::Tnet,
            total: None,
            ratios: Vec::new(),
            test_count: None,
            test_scenes: Vec::new(),
            plus_synth: Vec::new(),
            budget: TrainBudgetOptions::default(),
            seed: 0,
            repeats: 1,
            quick: false,
            out: PathBuf::from("runs/mix"),
            force: false,
            jobs: None,
            command_line: Vec::new(),
        }
    }
}

/// `synthgen experiment sim2real`: train on synthetic frames only, test on real ones.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Sim2realOptions {
    /// Real frames the scene (and sensor) are fitted to.
    pub fit: Option<PathBuf>,
    /// Real test frames.
    pub test: PathBuf,
    /// Test scenes of `test` (held out of the fits).
    pub test_scenes: Vec<u32>,
    pub model: Sim2realModel,
    /// Frames per synthetic set. [default: 1500; small with quick]
    pub frames: Option<usize>,
    /// A scene file instead of a scene fit (RGB models).
    pub scene: Option<PathBuf>,
    /// Replacement meshes per object in every synthetic set (`model align --scans` writes them).
    pub models: Option<PathBuf>,
    /// Frames of the Cycles rows (RGB models). [default: 200; 4 with quick]
    pub cycles_frames: Option<usize>,
    pub budget: TrainBudgetOptions,
    /// Also the ablation rows.
    pub ablation: bool,
    /// Rest axis of objects the fit never saw.
    pub unseen_up: UpAxis,
    /// Training-time mask jitter, pixels.
    pub mask_jitter_px: u32,
    /// Training-time mask shift, pixels.
    pub mask_shift_px: u32,
    /// Training-time occluder probability.
    pub occlusion_prob: f64,
    /// Training-time point dropout.
    pub point_dropout: f64,
    /// TNet conditioned on the object class.
    pub per_object: bool,
    /// Models per row (centres averaged). [default: 3; 1 with quick]
    pub ensemble: Option<usize>,
    /// The depth models' centres refined on the real depth.
    pub refine: Refine,
    /// With `Refine::Edges` or `Views` (the RGB models): what of each test instance shows,
    /// which the refinement keeps to (`synthgen_jobs::rgb_refine::VisibleBoxes`).
    pub visible_box: VisibleBoxes,
    pub seed: u64,
    /// Only these rows.
    pub rows: Vec<String>,
    /// Share of a set's frames that may fail to render (left out).
    pub max_failed_fraction: f64,
    /// The detector of the `no_gt` scores.
    pub detector: DetectorChoice,
    /// Epochs of a detector trained here. [default: 30; 2 with quick]
    pub detector_epochs: Option<usize>,
    pub quick: bool,
    pub out: PathBuf,
    pub force: bool,
    pub jobs: Option<usize>,
    /// The command that reproduces this run, recorded in the manifests.
    pub command_line: Vec<String>,
}

impl Default for Sim2realOptions {
    fn default() -> Sim2realOptions {
        Sim2realOptions {
            fit: None,
            test: PathBuf::new(),
            test_scenes: Vec::new(),
            model: Sim2realModel::Tnet,
            frames: None,
            scene: None,
            models: None,
            cycles_frames: None,
            budget: TrainBudgetOptions::default(),
            ablation: false,
            unseen_up: UpAxis::Stable,
            mask_jitter_px: 3,
            mask_shift_px: 0,
            occlusion_prob: 0.0,
            point_dropout: 0.0,
            per_object: false,
            ensemble: None,
            refine: Refine::Icp,
            visible_box: VisibleBoxes::None,
            seed: 0,
            rows: Vec::new(),
            max_failed_fraction: 0.01,
            detector: DetectorChoice::Train,
            detector_epochs: None,
            quick: false,
            out: PathBuf::from("runs/sim2real"),
            force: false,
            jobs: None,
            command_line: Vec::new(),
        }
    }
}

/// `synthgen experiment rgb`: seed 001's Table 1, two translation parametrizations.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct RgbOptions {
    pub train: PathBuf,
    pub test: PathBuf,
    pub train_split: Option<String>,
    pub test_split: Option<String>,
    pub test_scenes: Vec<u32>,
    pub variants: Vec<Translation>,
    pub epochs: Option<usize>,
    pub batch: Option<usize>,
    pub lr: f64,
    pub width: Option<usize>,
    pub crop_size: Option<u32>,
    pub min_visib_fract: f64,
    pub seed: u64,
    pub quick: bool,
    pub out: PathBuf,
    pub force: bool,
    pub jobs: Option<usize>,
    /// The command that reproduces this run, recorded in the manifests.
    pub command_line: Vec<String>,
}

impl Default for RgbOptions {
    fn default() -> RgbOptions {
        RgbOptions {
            train: PathBuf::new(),
            test: PathBuf::new(),
            train_split: None,
            test_split: None,
            test_scenes: Vec::new(),
            variants: vec![Translation::CentreTz, Translation::Xyz],
            epochs: None,
            batch: None,
            lr: 2e-3,
            width: None,
            crop_size: None,
            min_visib_fract: 0.1,
            seed: 0,
            quick: false,
            out: PathBuf::from("runs/rgb"),
            force: false,
            jobs: None,
            command_line: Vec::new(),
        }
    }
}
