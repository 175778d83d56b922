//! Object symmetries as BOP's `models_info.json` stores them.

use serde::{Deserialize, Serialize};

/// A continuous symmetry: rotation about `axis` through `offset` (mm in BOP files).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ContinuousSymmetry {
    pub axis: [f64; 3],
    pub offset: [f64; 3],
}

/// Symmetries of one object: discrete ones as flattened row-major 4x4 matrices with the
/// translation in millimetres, continuous ones as axis + offset.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct Symmetries {
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub symmetries_discrete: Vec<[f64; 16]>,
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub symmetries_continuous: Vec<ContinuousSymmetry>,
}

impl Symmetries {
    pub fn is_empty(&self) -> bool {
        self.symmetries_discrete.is_empty() && self.symmetries_continuous.is_empty()
    }
}
