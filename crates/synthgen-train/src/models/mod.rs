//! The pose models. Only TNet is implemented so far (RNet and Full: see docs/training.md).

pub mod tnet;

use serde::{Deserialize, Serialize};

/// Which model a run trains.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum ModelKind {
    /// Object centre from the point cloud (PointNet offsets).
    Tnet,
    /// Rotation from colour + points (DenseFusion style). Not implemented yet.
    Rnet,
    /// Both heads with the per-point ADD loss. Not implemented yet.
    Full,
}

impl ModelKind {
    pub fn name(self) -> &'static str {
        match self {
            ModelKind::Tnet => "tnet",
            ModelKind::Rnet => "rnet",
            ModelKind::Full => "full",
        }
    }
}
