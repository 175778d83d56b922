//! `synthgen preview`: a contact sheet of frames with their ground-truth poses drawn on the
//! RGB (projected 3D bounding box, object axes, object id), to check annotations by eye.

use rand::seq::SliceRandom;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use synthgen_core::glam::DVec3;
use synthgen_core::rng::splitmix64;
use synthgen_core::{Intrinsics, Progress};

use synthgen_formats::bop::{read_rgb, ModelInfo};
use synthgen_formats::draw::{Canvas, Rgb};
use synthgen_formats::source::{FrameLocation, FrameSource, SourceFrame};
use synthgen_formats::{Error, Result};

/// Contact sheet settings.
#[derive(Debug, Clone, PartialEq)]
pub struct PreviewOptions {
    /// Frames on the sheet (fewer when the dataset has fewer).
    pub count: usize,
    /// Which frames: a seeded draw over all frames.
    pub seed: u64,
    /// Width of one tile in pixels; the height follows the image's aspect.
    pub tile_width: u32,
    /// Limit to these splits (all when empty).
    pub splits: Vec<String>,
}

impl Default for PreviewOptions {
    fn default() -> Self {
        PreviewOptions {
            count: 16,
            seed: 0,
            tile_width: 320,
            splits: Vec::new(),
        }
    }
}

/// Box colours per object, by id modulo 12 (the Linemod ids 1..15 get distinct colours
/// within any 12 consecutive ids).
pub const PALETTE: [Rgb; 12] = [
    [170, 170, 170],
    [0, 230, 255],
    [255, 0, 255],
    [255, 140, 0],
    [160, 255, 80],
    [255, 255, 255],
    [120, 160, 255],
    [255, 110, 110],
    [255, 220, 0],
    [0, 255, 170],
    [200, 120, 255],
    [255, 180, 200],
];

pub const AXIS_COLOURS: [Rgb; 3] = [[255, 0, 0], [0, 255, 0], [0, 90, 255]];

/// The 8 corners of a model's bounding box (metres, object frame).
pub fn box_corners(info: &ModelInfo) -> [DVec3; 8] {
    let min = DVec3::new(info.min_x, info.min_y, info.min_z) / 1000.0;
    let size = DVec3::new(info.size_x, info.size_y, info.size_z) / 1000.0;
    std::array::from_fn(|i| {
        min + size * DVec3::new((i & 1) as f64, ((i >> 1) & 1) as f64, ((i >> 2) & 1) as f64)
    })
}

/// Corner index pairs of the 12 box edges.
pub const EDGES: [(usize, usize); 12] = [
    (0, 1),
    (2, 3),
    (4, 5),
    (6, 7),
    (0, 2),
    (1, 3),
    (4, 6),
    (5, 7),
    (0, 4),
    (1, 5),
    (2, 6),
    (3, 7),
];

/// Projects a camera-frame point; `None` behind or too close to the camera.
fn project(k: &Intrinsics, p: DVec3) -> Option<(f64, f64)> {
    (p.z > 1e-3).then(|| (k.fx * p.x / p.z + k.cx, k.fy * p.y / p.z + k.cy))
}

/// Draws one frame's poses onto `tile` (already scaled by `scale` from the image).
pub fn draw_frame(
    tile: &mut Canvas,
    frame: &SourceFrame,
    models: &std::collections::BTreeMap<u32, ModelInfo>,
    scale: f64,
) {
    let k0 = frame.camera.intrinsics(tile.width, tile.height);
    let k = Intrinsics {
        fx: k0.fx * scale,
        fy: k0.fy * scale,
        cx: (k0.cx + 0.5) * scale - 0.5,
        cy: (k0.cy + 0.5) * scale - 0.5,
        ..k0
    };
    let thick = if tile.width >= 480 { 2 } else { 1 };
    for g in &frame.gt {
        let Some(info) = models.get(&g.obj_id) else {
            continue;
        };
        let pose = g.cam_from_obj();
        let colour = PALETTE[g.obj_id as usize % PALETTE.len()];
        let corners = box_corners(info).map(|c| project(&k, pose.transform_point(c)));
        for (a, b) in EDGES {
            if let (Some(a), Some(b)) = (corners[a], corners[b]) {
                tile.line(a, b, colour, thick);
            }
        }
        let half = info.diameter / 2000.0;
        let Some(origin) = project(&k, pose.translation_m) else {
            continue;
        };
        for (axis, colour) in AXIS_COLOURS.iter().enumerate() {
            let mut dir = DVec3::ZERO;
            dir[axis] = half;
            if let Some(end) = project(&k, pose.transform_point(dir)) {
                tile.line(origin, end, *colour, thick + 1);
            }
        }
        tile.text(
            origin.0.round() as i64 + 4,
            origin.1.round() as i64 + 4,
            &g.obj_id.to_string(),
            2,
            colour,
        );
    }
}

/// Draws the sheet. Returns it and the frames on it, in sheet order (row by row).
pub fn contact_sheet(
    source: &dyn FrameSource,
    opts: &PreviewOptions,
    progress: &dyn Progress,
) -> Result<(Canvas, Vec<FrameLocation>)> {
    let models = source
        .models_info()
        .cloned()
        .ok_or_else(|| Error::MissingFile {
            path: source.root().join("models").join("models_info.json"),
        })?;
    let mut frames = source.frames(&opts.splits)?;
    if frames.is_empty() {
        return Err(Error::InvalidRequest(format!(
            "no annotated frames in {}",
            source.root().display()
        )));
    }
    let mut rng = ChaCha8Rng::seed_from_u64(splitmix64(opts.seed ^ 0x7072_6576)); // "prev"
    frames.shuffle(&mut rng);
    frames.truncate(opts.count.max(1));
    frames.sort_by(|a, b| a.location.cmp(&b.location));

    let cam = source.camera();
    let tw = opts.tile_width.max(16);
    let th = ((tw as f64 * cam.height as f64 / cam.width as f64).round() as u32).max(1);
    let cols = (frames.len() as f64).sqrt().ceil() as u32;
    let rows = (frames.len() as u32).div_ceil(cols);
    let gap = 4;
    let mut sheet = Canvas::new(
        cols * (tw + gap) + gap,
        rows * (th + gap) + gap,
        [40, 40, 40],
    );
    progress.start("preview", frames.len() as u64);
    for (n, f) in frames.iter().enumerate() {
        let img = Canvas::from_image(read_rgb(&f.rgb)?);
        let scale = tw as f64 / img.width as f64;
        let mut tile = img.resized(tw, th);
        draw_frame(&mut tile, f, &models, scale);
        let (c, r) = (n as u32 % cols, n as u32 / cols);
        sheet.blit(&tile, gap + c * (tw + gap), gap + r * (th + gap));
        progress.advance(1);
    }
    progress.finish();
    Ok((sheet, frames.into_iter().map(|f| f.location).collect()))
}

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::expect_used)]
mod tests {
    use super::*;
    use synthgen_core::{Pose, Symmetries};
    use synthgen_formats::bop::{GtEntry, SceneCamera};

    #[test]
    fn box_is_drawn_where_the_object_projects() {
        let info = ModelInfo {
            diameter: 100.0,
            min_x: -20.0,
            min_y: -20.0,
            min_z: -20.0,
            size_x: 40.0,
            size_y: 40.0,
            size_z: 40.0,
            symmetries: Symmetries::default(),
        };
        let models = [(1u32, info)].into_iter().collect();
        let k = Intrinsics {
            width: 100,
            height: 100,
            fx: 100.0,
            fy: 100.0,
            cx: 49.5,
            cy: 49.5,
        };
        let pose = Pose::new(
            synthgen_core::glam::DMat3::IDENTITY,
            DVec3::new(0.0, 0.0, 0.5),
        );
        let frame = SourceFrame {
            location: FrameLocation {
                split: "s".into(),
                scene_id: 0,
                im_id: 0,
            },
            camera: SceneCamera::without_world(k.k_row_major(), 1.0),
            gt: vec![GtEntry::new(1, &pose)],
            gt_info: None,
            rgb: "x.png".into(),
            depth: None,
            masks: vec![],
            masks_visib: vec![],
        };
        let mut tile = Canvas::new(100, 100, [0, 0, 0]);
        draw_frame(&mut tile, &frame, &models, 1.0);
        // The front face (z = 0.48 m) has corners at 49.5 ± 100 * 0.02 / 0.48 ≈ ±4.2 px.
        let px = |x: usize, y: usize| tile.rgb[(y * 100 + x) * 3..(y * 100 + x) * 3 + 3].to_vec();
        assert_eq!(px(54, 46), PALETTE[1].to_vec());
        assert_eq!(px(10, 10), vec![0, 0, 0]);
    }
}
