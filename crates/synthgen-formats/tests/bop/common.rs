use std::path::{Path, PathBuf};

use synthgen_core::annotate::DEFAULT_VISIB_DELTA_M;
use synthgen_core::glam::{DMat3, DVec3};
use synthgen_core::sample::BackgroundSample;
use synthgen_core::scene::BackgroundKind;
use synthgen_core::{
    annotate, AloneDepth, FrameScene, Intrinsics, ObjectAnnotation, ObjectInstance, Pose,
    RenderedFrame,
};
use synthgen_formats::bop::{BopWriter, BopWriterOptions};

pub const W: u32 = 32;
pub const H: u32 = 24;

pub fn intrinsics() -> Intrinsics {
    Intrinsics {
        width: W,
        height: H,
        fx: 30.5,
        fy: 31.25,
        cx: 15.7,
        cy: 11.9,
    }
}

pub struct TestFrame {
    pub scene: FrameScene,
    pub frame: RenderedFrame,
    pub ann: Vec<ObjectAnnotation>,
}

fn rect(x0: i32, y0: i32, w: u32, h: u32, near_m: f32) -> AloneDepth {
    let depth_m = (0..w * h)
        .map(|i| near_m + 0.000_37 * (i % w) as f32 + 0.000_11 * (i / w) as f32)
        .collect();
    AloneDepth {
        x0,
        y0,
        width: w,
        height: h,
        depth_m,
    }
}

pub fn scene(frame_index: u64, objects: Vec<ObjectInstance>) -> FrameScene {
    let f = frame_index as f64;
    FrameScene {
        frame_index,
        intrinsics: intrinsics(),
        world_from_cam: Pose::world_from_cam_look_at(
            DVec3::new(0.3 + 0.01 * f, -0.2, 0.5),
            DVec3::new(0.0, 0.01 * f, 0.0),
            DVec3::Z,
        ),
        objects,
        distractors: vec![],
        lights: vec![],
        ambient: 0.3,
        shadows: false,
        ambient_occlusion: 0.0,
        shading: Default::default(),
        environment: None,
        ground: None,
        walls: vec![],
        background: BackgroundSample {
            kind: BackgroundKind::Noise,
            color: [0.5; 3],
            seed: frame_index,
        },
    }
}

pub fn instance(obj_id: u32, cam_from_obj: Pose) -> ObjectInstance {
    ObjectInstance {
        model_index: 0,
        obj_id,
        cam_from_obj,
        brightness: 1.0,
        specular: 0.0,
        shininess: 1.0,
        tint: [1.0; 3],
        hue_deg: 0.0,
        metallic: 0.0,
    }
}

/// Two rectangles: object 1 far, object 5 nearer, overlapping it and truncated by the right
/// image border. Frame 3 has a depth hole and a pixel too far for 16 bits at 0.1 mm.
pub fn test_frame(frame_index: u64) -> TestFrame {
    let f = frame_index as f64;
    let alone = vec![
        rect(3 + frame_index as i32, 4, 10, 8, 0.5 + 0.01 * f as f32),
        rect(8 + 4 * frame_index as i32, 6, 12, 10, 0.45),
    ];
    let n = (W * H) as usize;
    let mut depth = vec![1.234_567f32; n];
    let mut instance_ids = vec![0u16; n];
    for (i, a) in alone.iter().enumerate() {
        for y in 0..H as i32 {
            for x in 0..W as i32 {
                let d = a.at(x, y);
                let p = (y as u32 * W + x as u32) as usize;
                if d > 0.0 && d < depth[p] {
                    depth[p] = d;
                    instance_ids[p] = i as u16 + 1;
                }
            }
        }
    }
    if frame_index == 3 {
        depth[5] = 0.0;
        depth[6] = 7.0;
    }
    let ann = annotate(&intrinsics(), &depth, &alone, DEFAULT_VISIB_DELTA_M);
    let rgb = (0..n * 3)
        .map(|i| ((i * 37 + frame_index as usize * 11) % 251) as u8)
        .collect();
    let axis = DVec3::new(1.0, 2.0 + f, -0.5).normalize();
    let objects = vec![
        instance(
            1,
            Pose::new(
                DMat3::from_axis_angle(axis, 0.3 + f),
                DVec3::new(0.01 * f, -0.02, 0.5),
            ),
        ),
        instance(
            5,
            Pose::new(
                DMat3::from_axis_angle(DVec3::new(axis.y, axis.z, axis.x), -1.1 * f),
                DVec3::new(0.1234567, 0.0321, 0.45 + 0.001 * f),
            ),
        ),
    ];
    TestFrame {
        scene: scene(frame_index, objects),
        frame: RenderedFrame {
            width: W,
            height: H,
            rgb,
            depth_m: depth,
            instance: instance_ids,
            alone,
        },
        ann,
    }
}

pub fn options(chunk_size: u32) -> BopWriterOptions {
    let mut o = BopWriterOptions::new(intrinsics());
    o.chunk_size = chunk_size;
    o
}

/// Writes `frames` with one thread per frame, records added in reverse order.
pub fn write_frames(writer: &BopWriter, frames: &[u64]) {
    let records: Vec<_> = std::thread::scope(|s| {
        let handles: Vec<_> = frames
            .iter()
            .map(|&i| {
                s.spawn(move || {
                    let t = test_frame(i);
                    writer.write_frame(i, &t.scene, &t.frame, &t.ann).unwrap()
                })
            })
            .collect();
        handles.into_iter().map(|h| h.join().unwrap()).collect()
    });
    for r in records.into_iter().rev() {
        writer.add_record(r).unwrap();
    }
}

/// Every file under `dir`, recursively, relative paths sorted.
pub fn all_files(dir: &Path) -> Vec<PathBuf> {
    let mut out = Vec::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for e in std::fs::read_dir(&d).unwrap() {
            let p = e.unwrap().path();
            if p.is_dir() {
                stack.push(p);
            } else {
                out.push(p.strip_prefix(dir).unwrap().to_path_buf());
            }
        }
    }
    out.sort();
    out
}
