//! The `[distractors]` section of a scene spec and the checks of the fields added to the
//! `[camera]`, `[lights]` and `[materials]` sections for view rejection and colour
//! randomization (kept apart from scene.rs to keep that file small).

use std::path::PathBuf;

use serde::{Deserialize, Serialize};

use crate::range::Range;

/// A primitive distractor shape.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum DistractorShape {
    Box,
    Cylinder,
    Sphere,
}

/// Distractors: placed (and settled) with the targets, rendered, occluding them, but never
/// annotated (no `scene_gt` entry; the targets' `mask_visib` and `visib_fract` account for
/// them).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct DistractorSpec {
    /// Distractors per frame, inclusive range. Default 0..0 (none).
    pub count: [u32; 2],
    /// Primitive shapes to draw from. Default box, cylinder, sphere.
    pub shapes: Vec<DistractorShape>,
    /// Extent of a primitive along each axis, metres. Default 0.03..0.12.
    pub size_m: Range,
    /// Primitive sizes per shape, drawn once per run from `size_m` (the renderer holds a
    /// mesh per size). Default 6.
    pub variants: u32,
    /// sRGB colour range of primitives, per channel. Default 0.05..0.95.
    pub color_min: [f32; 3],
    pub color_max: [f32; 3],
    /// Other meshes used as distractors (paths relative to the spec file). Default none.
    pub meshes: Vec<PathBuf>,
    /// Units of `meshes`: `mm`, `m` or `auto` (default).
    pub units: Option<String>,
    /// Probability that a distractor is one of `meshes` rather than a primitive (when both
    /// exist). Default 0.5.
    pub mesh_probability: f64,
}

impl Default for DistractorSpec {
    fn default() -> Self {
        Self {
            count: [0, 0],
            shapes: vec![
                DistractorShape::Box,
                DistractorShape::Cylinder,
                DistractorShape::Sphere,
            ],
            size_m: [0.03, 0.12],
            variants: 6,
            color_min: [0.05; 3],
            color_max: [0.95; 3],
            meshes: Vec::new(),
            units: None,
            mesh_probability: 0.5,
        }
    }
}

#[cfg(test)]
mod tests {
    use crate::scene::{DistractorShape, SceneSpec};

    #[test]
    fn new_sections_parse_and_bad_values_name_the_field() {
        let s = SceneSpec::from_toml_str(
            "[camera]\nmin_visib_fract = 0.3\nallow_truncation = false\n[distractors]\ncount = [1, 3]\nshapes = [\"sphere\"]\n[lights]\ntemperature_k = [3000.0, 6500.0]\n[materials]\nroughness = [0.2, 0.6]\nhue_deg = [-20.0, 20.0]\nshading = \"ggx\"\nmetallic = [0.0, 0.4]\n",
        )
        .unwrap();
        assert_eq!(s.materials.shading, crate::scene::Shading::Ggx);
        assert_eq!(s.distractors.shapes, vec![DistractorShape::Sphere]);
        assert!(!s.camera.allow_truncation);
        assert_eq!(SceneSpec::from_toml_str(&s.to_toml()).unwrap(), s);
        for (bad, field) in [
            (
                "[camera]\nmin_visib_fract = 1.5\n",
                "camera.min_visib_fract",
            ),
            ("[camera]\nmax_view_tries = 0\n", "camera.max_view_tries"),
            ("[distractors]\ncount = [3, 1]\n", "distractors.count"),
            ("[distractors]\nsize_m = [0.0, 0.1]\n", "distractors.size_m"),
            (
                "[lights]\ntemperature_k = [500.0, 6500.0]\n",
                "lights.temperature_k",
            ),
            (
                "[materials]\nroughness = [0.5, 2.0]\n",
                "materials.roughness",
            ),
            (
                "[materials]\nshading = \"ggx\"\nmetallic = [0.0, 1.5]\n",
                "materials.metallic",
            ),
            (
                "[lights]\nambient_occlusion = -0.2\n",
                "lights.ambient_occlusion",
            ),
            (
                "[distractors]\ncount = [1, 2]\nshapes = []\n",
                "distractors.count",
            ),
        ] {
            let e = SceneSpec::from_toml_str(bad).unwrap_err().to_string();
            assert!(e.contains(field), "{bad}: {e}");
        }
    }
}
