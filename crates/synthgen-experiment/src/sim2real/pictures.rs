//! Pictures of a row's estimates over real test frames (issue 54): each estimate's model
//! points projected in its object's colour, the GT poses' as sparse white dots over them,
//! the object id at the estimate's centre; per test scene its first and its last frame.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use anyhow::{Context, Result};
use synthgen_core::glam::DVec3;
use synthgen_core::Pose;
use synthgen_formats::bop::read_rgb;
use synthgen_formats::draw::{Canvas, Rgb};
use synthgen_formats::source::{FrameSource, SourceFrame};
use synthgen_train::metrics::EvalObject;
use synthgen_train::results::Estimate;

/// The folder of the pictures in the experiment's output.
pub const PICTURES_DIR: &str = "pictures";

/// Colours of the objects, in the order of their ids.
const PALETTE: [Rgb; 8] = [
    [255, 70, 70],
    [60, 220, 60],
    [70, 140, 255],
    [255, 200, 0],
    [230, 70, 230],
    [0, 220, 220],
    [255, 140, 30],
    [170, 120, 255],
];

/// The first and the last frame of each scene among `frames`.
fn picked(frames: &[SourceFrame]) -> Vec<&SourceFrame> {
    let mut by_scene: BTreeMap<u32, Vec<&SourceFrame>> = BTreeMap::new();
    for f in frames {
        by_scene.entry(f.location.scene_id).or_default().push(f);
    }
    let mut out = Vec::new();
    for mut v in by_scene.into_values() {
        v.sort_by_key(|f| f.location.im_id);
        out.push(v[0]);
        if v.len() > 1 {
            out.push(v[v.len() - 1]);
        }
    }
    out
}

/// Draws `estimates` (the row `tag`'s) over the first and last of `frames` per scene into
/// `out/pictures/<tag>_<scene>_<image>.png`; returns the files written.
pub fn draw_estimates(
    out: &Path,
    tag: &str,
    frames: &[SourceFrame],
    estimates: &[Estimate],
    objects: &BTreeMap<u32, EvalObject>,
) -> Result<Vec<PathBuf>> {
    let dir = out.join(PICTURES_DIR);
    std::fs::create_dir_all(&dir).with_context(|| format!("cannot create {}", dir.display()))?;
    let colour = |id: u32| {
        let k = objects.keys().position(|&o| o == id).unwrap_or(0);
        PALETTE[k % PALETTE.len()]
    };
    let mut written = Vec::new();
    for f in picked(frames) {
        let (scene, im) = (f.location.scene_id, f.location.im_id);
        let img = read_rgb(&f.rgb)
            .with_context(|| format!("cannot read the test image {}", f.rgb.display()))?;
        let mut c = Canvas::from_image(img);
        let k = f.camera.cam_k;
        let project =
            |p: DVec3| (p.z > 1e-6).then(|| (k[0] * p.x / p.z + k[2], k[4] * p.y / p.z + k[5]));
        // At most `n` of the model's points, evenly strided.
        let dots =
            |c: &mut Canvas, obj: &EvalObject, pose: &Pose, col: Rgb, size: i64, n: usize| {
                let step = obj.points_m.len().div_ceil(n).max(1);
                for p in obj.points_m.iter().step_by(step) {
                    if let Some((u, v)) = project(pose.transform_point(*p)) {
                        c.fill_rect(u.round() as i64, v.round() as i64, size, size, col);
                    }
                }
            };
        for e in estimates
            .iter()
            .filter(|e| e.scene_id == scene && e.im_id == im)
        {
            let Some(obj) = objects.get(&e.obj_id) else {
                continue;
            };
            dots(&mut c, obj, &e.pose, colour(e.obj_id), 2, 600);
        }
        // The GT on top, sparse: white dots inside the colour where the estimate is right.
        for g in &f.gt {
            if let Some(obj) = objects.get(&g.obj_id) {
                dots(&mut c, obj, &g.cam_from_obj(), [255, 255, 255], 1, 250);
            }
        }
        for e in estimates
            .iter()
            .filter(|e| e.scene_id == scene && e.im_id == im)
        {
            if let Some((u, v)) = project(e.pose.translation_m) {
                c.text(
                    u as i64,
                    v as i64,
                    &e.obj_id.to_string(),
                    2,
                    colour(e.obj_id),
                );
            }
        }
        c.text(
            6,
            6,
            &format!("{tag} scene {scene} image {im}: estimates in colour, GT white dots"),
            2,
            [255, 255, 255],
        );
        let path = dir.join(format!("{tag}_{scene:06}_{im:06}.png"));
        c.write_png(&path)?;
        written.push(path);
    }
    Ok(written)
}

/// The test frames of `scenes` (all when empty) of `test`'s split `split`.
pub fn test_frames(
    test: &dyn FrameSource,
    split: &str,
    scenes: &[u32],
) -> Result<Vec<SourceFrame>> {
    Ok(test
        .annotation_frames(&[split.to_string()])?
        .into_iter()
        .filter(|f| scenes.is_empty() || scenes.contains(&f.location.scene_id))
        .collect())
}
