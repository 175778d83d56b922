//! `synthgen predict`'s arguments.

use std::path::PathBuf;

use clap::Args;

use crate::cli::{DeviceArg, RgbRefineArg};

pub const PREDICT_EXAMPLES: &str = "Examples:
  # Photographs and the camera's intrinsics (BOP's camera.json, or {\"K\": [fx,0,cx,0,fy,cy,0,0,1]}):
  synthgen predict --model runs/dense --detector runs/det --images photos/ \\
      --camera camera.json --out poses/

  # RGB-D (tnet, rnet, full): depth PNGs of the same names; camera.json's depth_scale
  # (value x depth_scale = mm):
  synthgen predict --model runs/full --detector runs/det --images rgb/ --depth depth/ \\
      --camera camera.json --out poses/

  # A dataset's frames (BOP, Linemod, YCB-Video; its GT is not read), scored afterwards:
  synthgen predict --model runs/dense --detector runs/det --data ../shared/data/lmo --out poses/
  synthgen eval --results poses/results.csv --data ../shared/data/lmo --bop

  # A ROS 2 bag (MCAP) from a RealSense: colour, aligned depth, camera info:
  synthgen predict --model runs/full --detector runs/det --bag run.mcap \\
      --image-topic /camera/color/image_raw \\
      --depth-topic /camera/aligned_depth_to_color/image_raw --out poses/

  # Pictures of what was found (boxes, masks, each pose's axes: x red, y green, z blue):
  synthgen predict --model runs/dense --detector runs/det --images photos/ \\
      --camera camera.json --out poses/ --draw poses/pictures

Per frame: the detector's boxes and masks (each object's best --per-object detections scoring
at least --min-score), then per detection the pose model: the RGB models read the colour
around the box, the depth models the points of the detection's mask. Writes OUT/results.csv
(BOP's results format: scene_id,im_id,obj_id,score,R,t,time; whole poses, mm) and
OUT/predictions.jsonl, one line per frame even when nothing was found:
{\"frame\", \"scene_id\", \"image_id\", \"stamp\", \"objects\": [{\"obj_id\", \"score\",
\"pose_score\", \"bbox\", \"R\" (row-major), \"t\" (metres), \"segmentation\" (COCO RLE)}],
\"time\": {\"read\", \"detect\", \"instances\", \"pose\", \"refine\", \"total\"} (seconds)}; from a bag,
\"frame\" is FRAME_ID@STAMP and \"stamp\" the image's header stamp. A TNet gives t
and no R, an RNet R and no t: they are in predictions.jsonl only. Prints the objects found
and the time per stage (median and 95th percentile per frame).";

#[derive(Debug, Args)]
#[command(group(clap::ArgGroup::new("frames").required(true).args(["images", "data", "bag"])))]
pub struct PredictArgs {
    /// The pose model: a `synthgen train` run folder (or its model.safetensors).
    #[arg(long, value_name = "DIR")]
    pub model: PathBuf,

    /// The detector: a `synthgen detector train` run folder (or its model.safetensors).
    #[arg(long, value_name = "DIR")]
    pub detector: PathBuf,

    /// A folder of photographs (PNG or JPEG), taken in name order; needs --camera. Image ids
    /// (results.csv's im_id) are the file names' numbers where each is one (000003.png: 3),
    /// else their places in name order; scene_id is 0.
    #[arg(long, value_name = "DIR", requires = "camera")]
    pub images: Option<PathBuf>,

    /// The intrinsics of --images: BOP's camera.json (fx, fy, cx, cy, width, height,
    /// depth_scale) or a JSON with "K" (nine numbers, row-major).
    #[arg(long, value_name = "FILE")]
    pub camera: Option<PathBuf>,

    /// With --images and an RGB-D model: a folder of 16-bit depth PNGs with the photographs'
    /// file stems (value × the camera's depth_scale = millimetres).
    #[arg(long, value_name = "DIR", requires = "images")]
    pub depth: Option<PathBuf>,

    /// A dataset's frames instead of --images (BOP, Linemod or YCB-Video); its GT is not used.
    #[arg(long, value_name = "DIR", conflicts_with_all = ["images", "camera"])]
    pub data: Option<PathBuf>,

    /// A ROS 2 bag in MCAP (`ros2 bag record -s mcap`) instead of --images: the messages of
    /// --image-topic (sensor_msgs/Image: rgb8, bgr8, rgba8, bgra8, mono8; or CompressedImage,
    /// JPEG/PNG), each with the CameraInfo in force.
    #[arg(long, value_name = "FILE", conflicts_with_all = ["images", "camera", "data"], requires = "image_topic")]
    pub bag: Option<PathBuf>,

    /// With --bag: the colour image topic (e.g. /camera/color/image_raw).
    #[arg(long, value_name = "TOPIC", requires = "bag")]
    pub image_topic: Option<String>,

    /// With --bag and an RGB-D model: the depth topic (16UC1 mm or 32FC1 m, registered to the
    /// colour image, e.g. /camera/aligned_depth_to_color/image_raw); each image takes the
    /// depth message nearest in stamp, within 50 ms.
    #[arg(long, value_name = "TOPIC", requires = "bag")]
    pub depth_topic: Option<String>,

    /// With --bag: the CameraInfo topic (default: camera_info beside --image-topic, as
    /// image_transport publishes it: /camera/color/image_raw → /camera/color/camera_info).
    #[arg(long, value_name = "TOPIC", requires = "bag")]
    pub camera_info_topic: Option<String>,

    /// With --data: the split (default: test, else the only split).
    #[arg(long, requires = "data")]
    pub split: Option<String>,

    /// The output folder: results.csv and predictions.jsonl.
    #[arg(long, value_name = "DIR")]
    pub out: PathBuf,

    /// Detections scoring less are left out (0.05 keeps what `detector run` keeps; a robot
    /// that must not act on false finds wants more, e.g. 0.3).
    #[arg(long, default_value_t = 0.05)]
    pub min_score: f64,

    /// At most this many of each object per frame, best first (1 to 100).
    #[arg(long, default_value_t = 1, value_parser = clap::builder::RangedU64ValueParser::<usize>::new().range(1..=100))]
    pub per_object: usize,

    /// Draw every frame's detections and poses into this folder (PNG per frame).
    #[arg(long, value_name = "DIR")]
    pub draw: Option<PathBuf>,

    /// Replace the predictions of an earlier run in --out.
    #[arg(long)]
    pub force: bool,

    #[command(flatten)]
    pub refine: RefineArgs,

    /// Worker threads (default: all cores).
    #[arg(long, short = 'j', value_parser = crate::cli::threads())]
    pub jobs: Option<usize>,

    #[arg(long, value_enum, default_value = "cpu")]
    pub device: DeviceArg,
}

/// `--refine` and `--refine-models` of `predict` and `ros`.
#[derive(Debug, Args)]
pub struct RefineArgs {
    /// Refine the RGB models' estimates on the image, each kept to its detection's box, as
    /// `eval --refine` does: edges (contours onto the image's edges), views (a search over
    /// rotations first, then edges and the model's colours; ~0.5 s an estimate on 2 cores).
    #[arg(long, value_enum, default_value_t = RgbRefineArg::None)]
    pub refine: RgbRefineArg,

    /// With --refine views: compare the image with these meshes' colours instead of the
    /// objects' models' (one subfolder per object, as `synthgen model align` writes).
    #[arg(long, value_name = "DIR")]
    pub refine_models: Option<PathBuf>,
}
