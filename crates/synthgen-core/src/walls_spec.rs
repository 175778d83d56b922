//! The `[walls]` section of a scene spec (vertical planes of a square room around the
//! scene), the checks of the ground-texture fields, and the per-frame sampling of both
//! (kept apart from scene.rs and sample.rs to keep those files small).

use std::path::PathBuf;

use serde::{Deserialize, Serialize};

use crate::range::Range;
use crate::Error;

/// Walls: up to four vertical rectangles, the sides of a square room centred on the scene
/// centre (the ground's centre), rendered as geometry (they have depth and occlude) with
/// instance id 0, never annotated. A wall the camera is not inside of is culled (not drawn).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct WallSpec {
    /// Walls per frame, inclusive range, 0..4; `n` walls are `n` consecutive sides of the
    /// room. Default 0..0 (no walls).
    pub count: [u32; 2],
    /// Distance from the scene centre to each wall (half the room's side), metres. Drawn
    /// once per frame. Default 2.0..3.0.
    pub distance_m: Range,
    /// Wall height above the ground plane, metres. Default 1.0..2.5.
    pub height_m: Range,
    /// sRGB colour range per channel; one colour per frame for every wall (it multiplies
    /// the texture when `texture_dir` is set). Default a light grey-beige.
    pub color_min: [f32; 3],
    pub color_max: [f32; 3],
    /// Folder of PNG/JPEG images (relative to the spec file); each frame draws one for all
    /// its walls, each wall with its own offset. Default: none (plain colour).
    pub texture_dir: Option<PathBuf>,
    /// Side of one texture tile along the wall, metres (vertically it keeps the image's
    /// aspect ratio). Default 1.0.
    pub texture_scale_m: f64,
}

impl Default for WallSpec {
    fn default() -> Self {
        Self {
            count: [0, 0],
            distance_m: [2.0, 3.0],
            height_m: [1.0, 2.5],
            color_min: [0.55, 0.52, 0.48],
            color_max: [0.9, 0.88, 0.85],
            texture_dir: None,
            texture_scale_m: 1.0,
        }
    }
}

pub(crate) fn check_colors(name: &str, lo: [f32; 3], hi: [f32; 3]) -> Result<(), Error> {
    for c in 0..3 {
        let (a, b) = (lo[c], hi[c]);
        if !(a.is_finite() && b.is_finite() && (0.0..=1.0).contains(&a) && a <= b && b <= 1.0) {
            return Err(Error::InvalidSpec(format!(
                "{name}.color_min and color_max must lie within 0..1 with min <= max per channel, got {lo:?} and {hi:?}"
            )));
        }
    }
    Ok(())
}

pub(crate) fn check_scale(name: &str, v: f64) -> Result<(), Error> {
    if !(v.is_finite() && (1e-3..=100.0).contains(&v)) {
        return Err(Error::InvalidSpec(format!(
            "{name} must lie within 0.001..100 metres, got {v}"
        )));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use crate::mesh::Model;
    use crate::sample::SceneObject;
    use crate::scene::SceneSpec;
    use crate::SceneSampler;

    fn sampler(toml: &str) -> SceneSampler {
        let spec = SceneSpec::from_toml_str(toml).unwrap();
        let m = Model::cuboid("box", glam::Vec3::splat(0.1));
        SceneSampler::new(spec, SceneObject::one_per_model(&[m.clone(), m]), 3).unwrap()
    }

    #[test]
    fn fields_parse_and_are_checked() {
        let s = SceneSpec::from_toml_str(
            "[ground]\ntexture_dir = \"t\"\ntexture_scale_m = 0.25\n[walls]\ncount = [1, 4]\n",
        )
        .unwrap();
        assert_eq!(s.ground.texture_scale_m, 0.25);
        assert_eq!(s.walls.count, [1, 4]);
        assert_eq!(s.walls.distance_m, [2.0, 3.0]);
        for (bad, field) in [
            ("[walls]\ncount = [1, 5]\n", "walls.count"),
            ("[walls]\ndistance_m = [0.0, 1.0]\n", "walls.distance_m"),
            ("[walls]\ncolor_max = [1.0, 2.0, 1.0]\n", "walls.color_min"),
            (
                "[ground]\ntexture_scale_m = 0.0\n",
                "ground.texture_scale_m",
            ),
            ("[walls]\ndoors = 1\n", "doors"),
        ] {
            let e = SceneSpec::from_toml_str(bad).unwrap_err().to_string();
            assert!(e.contains(field), "{bad}: {e}");
        }
    }

    #[test]
    fn textures_and_walls_use_their_own_streams() {
        let plain = sampler("");
        let textured = sampler(
            "[ground]\ntexture_dir = \"t\"\n[walls]\ncount = [2, 4]\ntexture_dir = \"w\"\n",
        );
        for f in 0..10 {
            let (a, b) = (plain.sample(f).unwrap(), textured.sample(f).unwrap());
            assert_eq!(a.objects, b.objects);
            assert_eq!(a.world_from_cam, b.world_from_cam);
            assert_eq!(a.lights, b.lights);
            let (ga, gb) = (a.ground.clone().unwrap(), b.ground.clone().unwrap());
            assert_eq!((ga.color, ga.texture_seed), (gb.color, gb.texture_seed));
            assert!(ga.texture.is_none() && gb.texture.is_some());
            assert!(a.walls.is_empty() && !b.walls.is_empty());
            // The ground reaches the walls.
            assert!(gb.size_m >= b.walls[0].width_m * std::f64::consts::SQRT_2 - 1e-9);
            assert_eq!(b, textured.sample(f).unwrap());
        }
    }

    #[test]
    fn walls_stand_on_the_plane_around_the_scene_with_the_camera_inside() {
        // Walls close enough that the camera is often outside some: those are culled.
        let s =
            sampler("[walls]\ncount = [4, 4]\ndistance_m = [0.3, 0.7]\nheight_m = [1.0, 1.0]\n");
        let (mut drawn, mut culled) = (0, 0);
        for f in 0..40 {
            let fr = s.sample(f).unwrap();
            for w in &fr.walls {
                // The camera (the origin of its frame) is on the inner side of every wall.
                let n = w.cam_from_wall.rotation.z_axis;
                assert!(n.dot(-w.cam_from_wall.translation_m) > 0.0);
                // Vertical, standing on z = 0, 1 m high, facing the scene centre.
                let world = fr.world_from_cam.compose(&w.cam_from_wall);
                assert!(world.rotation.z_axis.z.abs() < 1e-9);
                assert!((world.translation_m.z - 0.5).abs() < 1e-9);
                assert_eq!(w.height_m, 1.0);
            }
            drawn += fr.walls.len();
            culled += 4 - fr.walls.len();
        }
        assert!(drawn > 40 && culled > 5, "drawn {drawn}, culled {culled}");
    }
}
