//! The pose models: TNet (centre), RNet (rotation) and Full (both) on RGB-D, and the RGB model
//! (a whole pose from a box's colour crop), see docs/training.md.

pub mod full;
pub mod rgb;
pub mod rgb_dense;
pub mod rnet;
pub mod tnet;

use serde::{Deserialize, Serialize};

/// Which model a run trains.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum ModelKind {
    /// Object centre from the point cloud (PointNet offsets).
    Tnet,
    /// Rotation from colour + points (DenseFusion style), quaternion-confidence loss.
    Rnet,
    /// Both heads on shared point features, per-pixel ADD loss (min over symmetries).
    Full,
    /// A whole pose from the colour crop of a box, no depth (seed 001).
    Rgb,
    /// Per-pixel visibility and object coordinates from the colour crop of a box, the pose
    /// by PnP + RANSAC; no depth.
    #[serde(rename = "rgb-dense")]
    RgbDense,
}

impl ModelKind {
    pub fn name(self) -> &'static str {
        match self {
            ModelKind::Tnet => "tnet",
            ModelKind::Rnet => "rnet",
            ModelKind::Full => "full",
            ModelKind::Rgb => "rgb",
            ModelKind::RgbDense => "rgb-dense",
        }
    }

    /// Whether the model reads RGB crops.
    pub fn needs_rgb(self) -> bool {
        self != ModelKind::Tnet
    }

    /// Whether the model reads depth (the sampled points): all but the RGB models.
    pub fn needs_depth(self) -> bool {
        !self.is_rgb_only()
    }

    /// The RGB models: a whole pose from a box's colour crop, no depth.
    pub fn is_rgb_only(self) -> bool {
        matches!(self, ModelKind::Rgb | ModelKind::RgbDense)
    }

    /// Whether the model predicts a rotation (and so needs the objects' models to train).
    pub fn predicts_rotation(self) -> bool {
        self != ModelKind::Tnet
    }
}
