//! Arguments of `synthgen detector train`, `detector run` and `detector eval`.

use std::path::PathBuf;

use clap::{Args, Subcommand};

use super::DeviceArg;

#[derive(Debug, Subcommand)]
pub enum DetectorCommand {
    /// Train the box detector (a centre heatmap per object over whole frames) on a dataset's
    /// visible boxes; checkpoints after every epoch.
    #[command(after_long_help = DETECTOR_TRAIN_EXAMPLES)]
    Train(DetectorTrainArgs),
    /// Run a trained detector over a dataset's frames and write the boxes as BOP detections
    /// (JSON), with the recall per object where the frames have GT.
    #[command(after_long_help = DETECTOR_RUN_EXAMPLES)]
    Run(DetectorRunArgs),
    /// Score a BOP detections file (ours or any detector's: CNOS, SAM-6D, GDRNPP) against a
    /// dataset's GT as bop_toolkit's eval_bop22_coco.py does: box and mask AP, AP50, AP75, AR.
    #[command(after_long_help = DETECTOR_EVAL_EXAMPLES)]
    Eval(DetectorEvalArgs),
}

pub const DETECTOR_TRAIN_EXAMPLES: &str = "Examples:
  # A detector of the eight LM-O objects from the synthetic frames the pose model learns from:
  synthgen detector train --data data/lmo_synth --out runs/det

  # Fewer epochs, a larger input (objects smaller than ~40 px want one):
  synthgen detector train --data data/lmo_synth --out runs/det320 --epochs 20 --input 320x240

  # Continue a stopped run from its last epoch:
  synthgen detector train --data data/lmo_synth --out runs/det --resume

Every frame is resampled to --input (160x120: a quarter of a 640x480 frame); the map is a
quarter of that. Training windows zoom the frame by 1 to 1.4 at a random place, with colour
jitter, blur and noise. The boxes to find are the instances' visible boxes (scene_gt_info's
bbox_visib, else the visible masks') with visib_fract >= --min-visib-fract. Writes
OUT/config.json, OUT/model.safetensors and OUT/state.json after every epoch and a line of
OUT/metrics.jsonl (loss, and the recall at IoU 0.5 of the held-out frames' boxes).";

pub const DETECTOR_RUN_EXAMPLES: &str = "Examples:
  # The boxes of the 82 real LM-O photographs, then the RGB model cropped from them:
  synthgen detector run --checkpoint runs/det --data ../shared/data/lmo --out det_lmo.json
  synthgen eval --checkpoint runs/dense/model.safetensors --data ../shared/data/lmo \\
      --detections det_lmo.json --refine views --visible-box detected --bop

The file is BOP's detections format (the BOP 2023 default detections, COCO results): a list
of {\"scene_id\", \"image_id\", \"category_id\", \"score\", \"bbox\": [x, y, width, height],
\"time\"}. Per frame and object, the heatmap's local maxima scoring at least --min-score, at
most --per-class of them. Where the frames have GT, a table of the recall per object: the
share of visible boxes (visib_fract >= the training's) that the object's best detections,
as many as it has instances, overlap at IoU >= 0.5.";

pub const DETECTOR_EVAL_EXAMPLES: &str = "Examples:
  # The LM-O photographs' detections, boxes (and masks where the file has them):
  synthgen detector eval --detections det_lmo.json --data ../shared/data/lmo

  # Compare with a BOP submission, modal boxes, scores and the GT written for pycocotools:
  synthgen detector eval --detections cnos_lmo-test.json --data ../shared/data/lmo \\
      --bbox-type modal --out scores.json --gt-out gt_coco.json

  # Look at them: 8 photographs, GT masks against the detections' (green agree):
  synthgen detector eval --detections det_lmo.json --data ../shared/data/lmo --draw pictures

Scored as bop_toolkit's scripts/eval_bop22_coco.py scores BOP's 2D detection and
segmentation tasks (pycocotools' COCOeval): the images of the dataset's
test_targets_bop19.json (or --targets FILE, or --all-frames), every GT instance with a
visible pixel (the < 10 % visible ones too: pycocotools overwrites the \"ignore\" flag
bop_toolkit writes for them), its visible mask as the mask and its full silhouette's bounds
as the box (--bbox-type amodal, bop_toolkit's default). Masks come from the dataset, else are
rendered from the GT poses and models as `synthgen annotate` does. Entries of other images are
left out (and counted); segm scores the entries with a \"segmentation\" (COCO RLE).
Prints AP (IoU 0.50:0.95), AP50, AP75, AP by size, AR at 1/10/100 detections, per object.";

#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum BboxTypeArg {
    /// The full silhouette's bounds (bop_toolkit's default).
    Amodal,
    /// The visible mask's bounds.
    Modal,
}

#[derive(Debug, Args)]
pub struct DetectorEvalArgs {
    /// The detections (BOP 2023 default-detections format: a JSON list of {scene_id,
    /// image_id, category_id, score, bbox, segmentation?}).
    #[arg(long, value_name = "FILE")]
    pub detections: PathBuf,

    /// The dataset with the GT (BOP, Linemod or YCB-Video).
    #[arg(long, value_name = "DIR")]
    pub data: PathBuf,

    /// The split (default: test, else the only split).
    #[arg(long)]
    pub split: Option<String>,

    /// The images to score: a BOP targets file (default: the dataset's
    /// test_targets_bop19.json when it has one, else every frame).
    #[arg(long, value_name = "FILE", conflicts_with = "all_frames")]
    pub targets: Option<PathBuf>,

    /// Score every frame of the split, targets file or not.
    #[arg(long)]
    pub all_frames: bool,

    /// The GT box the detections' boxes are compared with.
    #[arg(long, value_enum, default_value_t = BboxTypeArg::Amodal)]
    pub bbox_type: BboxTypeArg,

    /// Write the scores as JSON (bop_toolkit's names: AP, AP50, ..., per object).
    #[arg(long, value_name = "FILE")]
    pub out: Option<PathBuf>,

    /// Write the COCO GT the detections were scored against (pycocotools reads it).
    #[arg(long, value_name = "FILE")]
    pub gt_out: Option<PathBuf>,

    /// Draw scored images into this folder (SCENE_IMAGE.png): each object's GT visible mask
    /// against its best detection's (green both, red the detection only, blue the GT only),
    /// GT boxes blue, detections' boxes red with object and score.
    #[arg(long, value_name = "DIR")]
    pub draw: Option<PathBuf>,

    /// How many images --draw draws, spread over the scored ones.
    #[arg(long, default_value_t = 8, value_parser = clap::builder::RangedU64ValueParser::<usize>::new().range(1..=10_000))]
    pub draw_count: usize,

    /// Worker threads (default: all cores).
    #[arg(long, short = 'j', value_parser = crate::cli::threads())]
    pub jobs: Option<usize>,
}

#[derive(Debug, Args)]
pub struct DetectorTrainArgs {
    /// The training dataset (BOP, Linemod or YCB-Video); with --resume, the run's own (it
    /// may be left out).
    #[arg(long, value_name = "DIR", required_unless_present = "resume")]
    pub data: Option<PathBuf>,

    /// The run folder.
    #[arg(long, value_name = "DIR")]
    pub out: PathBuf,

    /// The split to train on (default: test, else the only split).
    #[arg(long)]
    pub split: Option<String>,

    /// The object ids to detect (default: every object of the split).
    #[arg(long, value_delimiter = ',', num_args = 1.., value_name = "ID")]
    pub objects: Vec<u32>,

    #[arg(long, default_value_t = 30)]
    pub epochs: usize,

    /// Frames per step.
    #[arg(long, default_value_t = 16)]
    pub batch: usize,

    #[arg(long, default_value_t = 2e-3)]
    pub lr: f64,

    /// The network's input, WIDTHxHEIGHT, multiples of 8.
    #[arg(long, default_value = "160x120", value_parser = parse_size)]
    pub input: [u32; 2],

    #[arg(long, default_value_t = 0)]
    pub seed: u64,

    /// Share of the frames held out for validation.
    #[arg(long, default_value_t = 0.1)]
    pub val_fraction: f64,

    /// Boxes only: no mask branch (by default the detector also learns each object's
    /// visible mask and gives every detection its mask as COCO RLE).
    #[arg(long)]
    pub no_masks: bool,

    /// Instances less visible than this are not boxes to find.
    #[arg(long, default_value_t = 0.1)]
    pub min_visib_fract: f64,

    /// Continue the run in --out from its checkpoint, as it was configured: --epochs may be
    /// raised; a setting that makes the run (--lr, --batch, --input, ...) given with another
    /// value than the run's is refused.
    #[arg(long, conflicts_with = "force")]
    pub resume: bool,

    /// Replace a run already in --out.
    #[arg(long)]
    pub force: bool,

    /// Worker threads (default: all cores).
    #[arg(long, short = 'j', value_parser = crate::cli::threads())]
    pub jobs: Option<usize>,

    #[arg(long, value_enum, default_value = "cpu")]
    pub device: DeviceArg,
}

#[derive(Debug, Args)]
pub struct DetectorRunArgs {
    /// The detector's run folder (or its model.safetensors, config.json beside it).
    #[arg(long, value_name = "PATH")]
    pub checkpoint: PathBuf,

    /// The frames to detect in (BOP, Linemod or YCB-Video).
    #[arg(long, value_name = "DIR")]
    pub data: PathBuf,

    /// The detections file to write (JSON; a folder gets detections.json), with its
    /// provenance beside it (NAME.provenance.json: the frames and objects it is of).
    #[arg(long, value_name = "FILE")]
    pub out: PathBuf,

    /// The split (default: test, else the only split).
    #[arg(long)]
    pub split: Option<String>,

    /// Peaks scoring less are not detections.
    #[arg(long, default_value_t = 0.05)]
    pub min_score: f64,

    /// At most this many detections per object and frame (1 to 100).
    #[arg(long, default_value_t = 10, value_parser = clap::builder::RangedU64ValueParser::<usize>::new().range(1..=100))]
    pub per_class: usize,

    /// Worker threads (default: all cores).
    #[arg(long, short = 'j', value_parser = crate::cli::threads())]
    pub jobs: Option<usize>,

    #[arg(long, value_enum, default_value = "cpu")]
    pub device: DeviceArg,
}

/// "160x120" → [160, 120].
fn parse_size(s: &str) -> Result<[u32; 2], String> {
    let (w, h) = s
        .split_once(['x', 'X'])
        .ok_or_else(|| format!("{s}: expected WIDTHxHEIGHT, e.g. 160x120"))?;
    let p = |v: &str| {
        v.trim()
            .parse::<u32>()
            .map_err(|_| format!("{s}: expected WIDTHxHEIGHT, e.g. 160x120"))
    };
    Ok([p(w)?, p(h)?])
}
