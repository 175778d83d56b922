//! `synthgen ros`'s arguments.

use std::path::PathBuf;

use clap::Args;

use crate::cli::{DeviceArg, RefineArgs};

pub const ROS_EXAMPLES: &str = "Examples:
  # Beside a RealSense driver (realsense2_camera, align_depth.enable:=true), RGB-D model:
  synthgen ros --model runs/full --detector runs/det \\
      --image-topic /camera/camera/color/image_raw \\
      --depth-topic /camera/camera/aligned_depth_to_color/image_raw

  # An RGB model, a 10-minute run recorded to a bag, on ROS_DOMAIN_ID 7:
  ROS_DOMAIN_ID=7 synthgen ros --model runs/dense --detector runs/det \\
      --image-topic /camera/image_raw --duration 600 --record detections.mcap

  # Then, on a machine with ROS 2 (Humble, Jazzy) and vision_msgs installed:
  ros2 topic echo /synthgen/detections vision_msgs/msg/Detection3DArray

A ROS 2 node with no ROS installation (ros2-client over RustDDS: speaks DDS/RTPS to Fast DDS
and Cyclone DDS, the RMWs of Humble and Jazzy). Subscribes --image-topic (sensor_msgs/Image:
rgb8, bgr8, rgba8, bgra8, mono8), --camera-info-topic (sensor_msgs/CameraInfo: K and the size
it is for) and, for tnet, rnet and full, --depth-topic (16UC1 mm or 32FC1 m, registered to the
colour image; paired by stamp within 50 ms), with ROS 2's sensor-data QoS (best effort, keep
last 5). Per colour image publishes, reliable, keep last 10:
  --detections-topic  vision_msgs/Detection3DArray: per object, results[0].hypothesis
                      (class_id = the BOP object id, score = the detection's), its pose (metres,
                      in the image's frame_id, stamped with the image's stamp) and bbox (centre
                      = the model's origin, size = the model's extents); a TNet's centre comes
                      with identity orientation and the rotation's variances -1 (not estimated)
  --detections-2d-topic  vision_msgs/Detection2DArray: every detection's box (pixels)
An empty array when nothing was found. When images come faster than the models run, the newest
replaces the one waiting (the count is reported). Bad input (an unknown encoding, no camera info
yet, an image whose size is not its camera info's, no depth within 50 ms) is logged and
skipped; the node keeps running. Relative topic names resolve under --namespace. A status line
every --status-every seconds (frames, rate, latency, memory); Ctrl-C stops the node, finishes
--record and prints a summary.";

#[derive(Debug, Args)]
pub struct RosArgs {
    /// The pose model: a `synthgen train` run folder (or its model.safetensors).
    #[arg(long, value_name = "DIR")]
    pub model: PathBuf,

    /// The detector: a `synthgen detector train` run folder (or its model.safetensors).
    #[arg(long, value_name = "DIR")]
    pub detector: PathBuf,

    /// The colour image topic (sensor_msgs/Image).
    #[arg(long, value_name = "TOPIC", default_value = "/camera/color/image_raw")]
    pub image_topic: String,

    /// The depth topic, registered to the colour image (needed by tnet, rnet, full).
    #[arg(long, value_name = "TOPIC")]
    pub depth_topic: Option<String>,

    /// The CameraInfo topic (default: camera_info beside --image-topic, as image_transport
    /// publishes it: /camera/color/image_raw → /camera/color/camera_info).
    #[arg(long, value_name = "TOPIC")]
    pub camera_info_topic: Option<String>,

    /// The vision_msgs/Detection3DArray topic published.
    #[arg(long, value_name = "TOPIC", default_value = "synthgen/detections")]
    pub detections_topic: String,

    /// The vision_msgs/Detection2DArray topic published.
    #[arg(long, value_name = "TOPIC", default_value = "synthgen/detections_2d")]
    pub detections_2d_topic: String,

    /// The node's namespace; relative topic names resolve under it.
    #[arg(long, default_value = "/")]
    pub namespace: String,

    /// The node's name.
    #[arg(long, default_value = "synthgen")]
    pub node_name: String,

    /// The DDS domain, 0 to 232 (default: $ROS_DOMAIN_ID, else 0).
    #[arg(long, value_parser = clap::value_parser!(u16).range(0..=232))]
    pub domain_id: Option<u16>,

    /// Detections scoring less are left out.
    #[arg(long, default_value_t = 0.05)]
    pub min_score: f64,

    /// At most this many of each object per frame, best first (1 to 100).
    #[arg(long, default_value_t = 1, value_parser = clap::builder::RangedU64ValueParser::<usize>::new().range(1..=100))]
    pub per_object: usize,

    /// Record what the node publishes into this MCAP file (a ROS 2 bag: ros2 bag play,
    /// Foxglove, the mcap and rosbags Python libraries read it).
    #[arg(long, value_name = "FILE")]
    pub record: Option<PathBuf>,

    /// Replace an existing --record file.
    #[arg(long)]
    pub force: bool,

    /// Stop after this many frames.
    #[arg(long, value_name = "N")]
    pub max_frames: Option<usize>,

    /// Stop after this many seconds.
    #[arg(long, value_name = "SECONDS")]
    pub duration: Option<f64>,

    /// A status line every this many seconds (0: none).
    #[arg(long, value_name = "SECONDS", default_value_t = 10.0)]
    pub status_every: f64,

    #[command(flatten)]
    pub refine: RefineArgs,

    /// Worker threads (default: all cores).
    #[arg(long, short = 'j', value_parser = crate::cli::threads())]
    pub jobs: Option<usize>,

    #[arg(long, value_enum, default_value = "cpu")]
    pub device: DeviceArg,
}
