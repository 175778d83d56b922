//! The detector on one 640x480 frame, as `synthgen detector run` spends it per frame once the
//! image is decoded: the frame resampled to the input (160x120), the network, the heatmaps'
//! peaks and, with masks, each detection's mask as COCO RLE. The 8 LM-O classes, at most 10
//! detections per class scoring ≥ 0.05 (`detector run`'s defaults). The weights are the
//! seeded initial ones (a trained detector is not in the repository): their heatmaps give
//! more peaks than a trained one's, 80 detections a frame, so the mask and RLE cost here is
//! an upper bound. The frame is a real LM-O photograph (../shared/data/lmo).
#![allow(clippy::unwrap_used, clippy::expect_used)]

#[global_allocator]
static GLOBAL: mimalloc::MiMalloc = mimalloc::MiMalloc;

use std::path::Path;

use candle_core::Device;
use criterion::{criterion_group, criterion_main, Criterion};
use synthgen_detect::detector::{Detector, DetectorConfig};

const CLASSES: [u32; 8] = [1, 5, 6, 8, 9, 10, 11, 12];

fn detect(c: &mut Criterion) {
    let photo = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../../shared/data/lmo/test/000002/rgb/000003.png");
    let img = synthgen_formats::bop::read_rgb_sized(&photo, [640, 480]).unwrap();
    for masks in [false, true] {
        let cfg = DetectorConfig {
            masks,
            ..DetectorConfig::new("unused".into(), "test".into(), CLASSES.to_vec())
        };
        let det = Detector::new(cfg, &Device::Cpu).unwrap();
        let found = det
            .detect_image(&img.rgb, img.width, img.height, 0.05, 10)
            .unwrap();
        eprintln!("masks {masks}: {} detections", found.len());
        let name = if masks {
            "detect_frame_masks_640x480_c8"
        } else {
            "detect_frame_640x480_c8"
        };
        c.bench_function(name, |b| {
            b.iter(|| {
                det.detect_image(&img.rgb, img.width, img.height, 0.05, 10)
                    .unwrap()
                    .len()
            })
        });
    }
}

criterion_group! {
    name = benches;
    config = Criterion::default().sample_size(20);
    targets = detect
}
criterion_main!(benches);
