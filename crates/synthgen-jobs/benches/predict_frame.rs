//! `synthgen predict`'s (and the ROS 2 node's) work per 640x480 frame once the image is decoded:
//! the detector (boxes and masks, the 8 LM-O objects, each object's best detection), then the
//! dense RGB model on each detection's crop with PnP + RANSAC: `Predictor::predict_image`.
//! The frame is a real LM-O photograph (../shared/data/lmo).
//!
//! The models: `SYNTHGEN_BENCH_MODEL` and `SYNTHGEN_BENCH_DETECTOR`, run folders of trained
//! models (e.g. those of `synthgen experiment sim2real --model rgb-dense`); without them the
//! bench says so and times nothing (trained models are not in the repository, and untrained
//! ones would time other work: a seeded detector's heatmaps have many more peaks). With
//! --min-score 0 every object gets its one detection: 8 pose estimates a frame, the most
//! LM-O's photographs ask for.
//! After criterion's median, the stages' shares, median and 95th percentile over 50 frames are
//! printed (docs/predict.md, "Latency").
#![allow(clippy::unwrap_used, clippy::expect_used)]

#[global_allocator]
static GLOBAL: mimalloc::MiMalloc = mimalloc::MiMalloc;

use std::path::{Path, PathBuf};
use std::time::Instant;

use criterion::{criterion_group, criterion_main, Criterion};
use synthgen_core::progress::NoProgress;
use synthgen_jobs::predict::{Predictor, PredictorOptions};
use synthgen_jobs::rgb_refine::refine_options;
use synthgen_jobs::Log;

/// The models named by the environment, else None (the bench says how to get them).
fn models() -> Option<(PathBuf, PathBuf)> {
    match (
        std::env::var("SYNTHGEN_BENCH_MODEL"),
        std::env::var("SYNTHGEN_BENCH_DETECTOR"),
    ) {
        (Ok(m), Ok(d)) => Some((m.into(), d.into())),
        _ => None,
    }
}

fn percentile(v: &mut [f64], q: f64) -> f64 {
    v.sort_by(f64::total_cmp);
    v[((v.len() - 1) as f64 * q).round() as usize]
}

fn predict(c: &mut Criterion) {
    let lmo = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../../shared/data/lmo");
    let Some((model, detector)) = models() else {
        eprintln!(
            "predict_frame: not run. It times trained models (a seeded initial detector finds \
             ten times the peaks a trained one does): set SYNTHGEN_BENCH_MODEL to an rgb-dense \
             run folder and SYNTHGEN_BENCH_DETECTOR to a detector run folder of the LM-O \
             objects, e.g. those of `synthgen experiment sim2real --model rgb-dense --scene \
             scenes/linemod_rgb.toml --test ../shared/data/lmo --out RUN` \
             (RUN/rows/synth_realistic/train and RUN/detector); docs/ros.md"
        );
        return;
    };
    let photo = lmo.join("test/000002/rgb/000003.png");
    let img = synthgen_formats::bop::read_rgb_sized(&photo, [640, 480]).unwrap();
    let k = [
        572.4114, 0.0, 325.2611, 0.0, 573.57043, 242.04899, 0.0, 0.0, 1.0,
    ];
    // Without the refinement, then with `--refine edges`.
    for refine in ["none", "edges"] {
        let p = Predictor::load(
            &PredictorOptions {
                model: model.clone(),
                detector: detector.clone(),
                objects_from: Some(lmo.clone()),
                min_score: 0.0,
                per_object: 1,
                cuda: false,
                refine: refine_options(refine).unwrap(),
                refine_models: None,
            },
            &Log::new(&NoProgress),
        )
        .unwrap();
        let once = || p.predict_image(&img, None, &k, (2, 3)).unwrap();
        eprintln!("{} objects a frame", once().objects.len());
        let name = match refine {
            "none" => "predict_frame_640x480_rgb_dense_c8".to_string(),
            r => format!("predict_frame_640x480_rgb_dense_c8_refine_{r}"),
        };
        c.bench_function(&name, |b| b.iter(|| once().objects.len()));
        let mut stages: [Vec<f64>; 5] = Default::default();
        for _ in 0..50 {
            let t = Instant::now();
            let f = once();
            stages[0].push(t.elapsed().as_secs_f64() * 1e3);
            stages[1].push(f.detect_s * 1e3);
            stages[2].push(f.instances_s * 1e3);
            stages[3].push(f.pose_s * 1e3);
            stages[4].push(f.refine_s * 1e3);
        }
        let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len() as f64;
        let all = mean(&stages[0]);
        let [total, det, inst, pose, refined] = &mut stages;
        eprintln!(
            "{name}, 50 frames: total median {:.1} ms, p95 {:.1} ms; shares of the mean: detect {:.0} %, instances {:.0} %, pose (network + PnP) {:.0} %, refine {:.0} %",
            percentile(&mut total.clone(), 0.5),
            percentile(total, 0.95),
            100.0 * mean(det) / all,
            100.0 * mean(inst) / all,
            100.0 * mean(pose) / all,
            100.0 * mean(refined) / all,
        );
        eprintln!(
            "stage medians: detect {:.1} ms, instances {:.1} ms, pose {:.1} ms, refine {:.1} ms",
            percentile(det, 0.5),
            percentile(inst, 0.5),
            percentile(pose, 0.5),
            percentile(refined, 0.5)
        );
    }
}

criterion_group! {
    name = benches;
    config = Criterion::default().sample_size(20);
    targets = predict
}
criterion_main!(benches);
