//! Encoding cost of one 640x480 BOP frame (1 RGB, 1 depth, 10 masks for 5 objects) per PNG
//! compression setting. `cargo run --release -p synthgen-formats --example png_timing`.

// A measurement tool, not library code: failing loudly is what it should do.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use std::path::Path;
use std::time::Instant;

use synthgen_core::glam::DVec3;
use synthgen_core::sample::BackgroundSample;
use synthgen_core::scene::BackgroundKind;
use synthgen_core::{
    FrameScene, GtInfo, Intrinsics, ObjectAnnotation, ObjectInstance, Pose, RenderedFrame,
};
use synthgen_formats::bop::image::{
    depth_to_png_values, encode_gray16_png, encode_gray8_png, encode_rgb_jpeg, encode_rgb_png,
};
use synthgen_formats::bop::{BopWriter, BopWriterOptions, PngCompression, RgbFormat};

const W: u32 = 640;
const H: u32 = 480;

struct XorShift(u64);
impl XorShift {
    fn next(&mut self) -> u32 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        (self.0 >> 32) as u32
    }
}

/// Ellipses standing in for 5 objects: (cx, cy, rx, ry).
const OBJECTS: [(f32, f32, f32, f32); 5] = [
    (160.0, 140.0, 70.0, 90.0),
    (330.0, 250.0, 90.0, 60.0),
    (480.0, 160.0, 60.0, 80.0),
    (250.0, 380.0, 80.0, 55.0),
    (520.0, 360.0, 65.0, 70.0),
];

fn inside(o: usize, x: u32, y: u32) -> bool {
    let (cx, cy, rx, ry) = OBJECTS[o];
    let (dx, dy) = ((x as f32 - cx) / rx, (y as f32 - cy) / ry);
    dx * dx + dy * dy <= 1.0
}

/// RGB with a per-pixel noise background (the worst case for PNG) or a smooth textured
/// ground, and shaded objects with a little sensor noise.
fn rgb(noise_background: bool) -> Vec<u8> {
    let mut rng = XorShift(0x9e37_79b9_7f4a_7c15);
    let mut out = Vec::with_capacity((W * H * 3) as usize);
    for y in 0..H {
        for x in 0..W {
            let obj = (0..5).find(|&o| inside(o, x, y));
            let n = (rng.next() % 7) as i32 - 3;
            let px: [i32; 3] = match obj {
                Some(o) => {
                    let shade = 80 + ((x + 2 * y) % 120) as i32 / 2 + 20 * o as i32;
                    [shade + n, shade / 2 + 40 + n, 200 - shade / 3 + n]
                }
                None if noise_background => {
                    let r = rng.next();
                    [
                        (r & 255) as i32,
                        ((r >> 8) & 255) as i32,
                        ((r >> 16) & 255) as i32,
                    ]
                }
                None => {
                    let t = (((x / 16 + y / 16) % 2) * 30) as i32 + (y / 4) as i32;
                    [90 + t + n, 100 + t + n, 80 + t / 2 + n]
                }
            };
            out.extend(px.map(|v| v.clamp(0, 255) as u8));
        }
    }
    out
}

fn depth_m() -> Vec<f32> {
    let mut rng = XorShift(7);
    (0..W * H)
        .map(|i| {
            let (x, y) = (i % W, i / W);
            let ground = 1.4 - 0.0012 * y as f32;
            let d = match (0..5).find(|&o| inside(o, x, y)) {
                Some(o) => 0.8 + 0.05 * o as f32 + 0.0002 * (x % 50) as f32,
                None => ground,
            };
            d + (rng.next() % 5) as f32 * 0.0001
        })
        .collect()
}

fn masks() -> Vec<Vec<u8>> {
    (0..10)
        .map(|m| {
            (0..W * H)
                .map(|i| if inside(m % 5, i % W, i / W) { 255 } else { 0 })
                .collect()
        })
        .collect()
}

/// Median milliseconds and the output size of `f`.
fn time(reps: usize, mut f: impl FnMut() -> usize) -> (f64, usize) {
    let mut t = Vec::with_capacity(reps);
    let mut size = 0;
    for _ in 0..reps {
        let s = Instant::now();
        size = f();
        t.push(s.elapsed().as_secs_f64() * 1e3);
    }
    t.sort_by(|a, b| a.total_cmp(b));
    (t[reps / 2], size)
}

fn main() {
    let p = Path::new("timing.png");
    let reps = 15;
    let (rgb_noise, rgb_smooth) = (rgb(true), rgb(false));
    let depth = depth_m();
    let masks = masks();
    println!("640x480, median of {reps}; per frame = rgb + depth + 10 masks (5 objects)");
    println!(
        "{:<9} {:>16} {:>16} {:>14} {:>14} {:>12} {:>12}",
        "setting",
        "rgb noise bg",
        "rgb smooth",
        "depth u16",
        "mask x1",
        "frame noise",
        "frame smooth"
    );
    for c in [
        PngCompression::Fastest,
        PngCompression::Fast,
        PngCompression::Balanced,
        PngCompression::High,
    ] {
        let (tn, sn) = time(reps, || {
            encode_rgb_png(&rgb_noise, W, H, c, p).unwrap().len()
        });
        let (ts, ss) = time(reps, || {
            encode_rgb_png(&rgb_smooth, W, H, c, p).unwrap().len()
        });
        let (td, sd) = time(reps, || {
            let (v, _) = depth_to_png_values(&depth, 0.1);
            encode_gray16_png(&v, W, H, c, p).unwrap().len()
        });
        let (tm, sm) = time(reps, || {
            encode_gray8_png(&masks[0], W, H, c, p).unwrap().len()
        });
        let tm10 = time(3, || {
            masks
                .iter()
                .map(|m| encode_gray8_png(m, W, H, c, p).unwrap().len())
                .sum()
        })
        .0;
        println!(
            "{:<9} {:>7.2} ms {:>4} kB {:>7.2} ms {:>4} kB {:>6.2} ms {:>3} kB {:>6.2} ms {:>2} kB {:>9.2} ms {:>9.2} ms",
            format!("{c:?}"),
            tn,
            sn / 1024,
            ts,
            ss / 1024,
            td,
            sd / 1024,
            tm,
            sm / 1024,
            tn + td + tm10,
            ts + td + tm10,
        );
    }
    for q in [90, 95] {
        let (tn, sn) = time(reps, || {
            encode_rgb_jpeg(&rgb_noise, W, H, q, p).unwrap().len()
        });
        let (ts, ss) = time(reps, || {
            encode_rgb_jpeg(&rgb_smooth, W, H, q, p).unwrap().len()
        });
        println!(
            "{:<9} {:>7.2} ms {:>4} kB {:>7.2} ms {:>4} kB",
            format!("jpeg q{q}"),
            tn,
            sn / 1024,
            ts,
            ss / 1024
        );
    }
    for c in [PngCompression::Fastest, PngCompression::Fast] {
        for fmt in [RgbFormat::Png, RgbFormat::Jpg { quality: 95 }] {
            let ms = full_frames(&rgb_noise, &depth, &masks, c, fmt);
            println!(
                "BopWriter::write_frame, {c:?}, {fmt:?}, noise bg, 1 thread: {ms:.2} ms/frame"
            );
        }
    }
}

/// Median time of `BopWriter::write_frame` + `add_record` over 40 frames written to a temp
/// folder: encoding plus 12 atomic file writes.
fn full_frames(
    rgb: &[u8],
    depth: &[f32],
    masks: &[Vec<u8>],
    c: PngCompression,
    fmt: RgbFormat,
) -> f64 {
    let dir = tempfile::tempdir().expect("temp dir");
    let k = Intrinsics::LINEMOD;
    let mut opts = BopWriterOptions::new(k);
    opts.png_compression = c;
    opts.rgb_format = fmt;
    let writer = BopWriter::create(dir.path(), opts).expect("writer");
    let objects: Vec<ObjectInstance> = (0..5)
        .map(|o| ObjectInstance {
            model_index: o,
            obj_id: o as u32 + 1,
            cam_from_obj: Pose::new(Default::default(), DVec3::new(0.0, 0.0, 0.8)),
            brightness: 1.0,
            specular: 0.0,
            shininess: 1.0,
            tint: [1.0; 3],
            hue_deg: 0.0,
            metallic: 0.0,
        })
        .collect();
    let ann: Vec<ObjectAnnotation> = (0..5)
        .map(|o| ObjectAnnotation {
            mask: masks[o].clone(),
            mask_visib: masks[o + 5].clone(),
            info: GtInfo {
                bbox_obj: [1, 2, 3, 4],
                bbox_visib: [1, 2, 3, 4],
                px_count_all: 100,
                px_count_valid: 100,
                px_count_visib: 90,
                visib_fract: 0.9,
            },
        })
        .collect();
    let frame = RenderedFrame {
        width: W,
        height: H,
        rgb: rgb.to_vec(),
        depth_m: depth.to_vec(),
        instance: vec![],
        alone: vec![],
    };
    let mut i = 0u64;
    time(40, || {
        let scene = FrameScene {
            frame_index: i,
            intrinsics: k,
            world_from_cam: Pose::IDENTITY,
            objects: objects.clone(),
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
                seed: 0,
            },
        };
        let rec = writer.write_frame(i, &scene, &frame, &ann).expect("write");
        writer.add_record(rec).expect("add");
        i += 1;
        0
    })
    .0
}
