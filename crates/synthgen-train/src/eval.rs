//! Scoring pose estimates against a dataset's ground truth (BOP or Linemod): matching, per-object
//! accuracies and mean errors (conventions in docs/metrics.md).

use std::collections::BTreeMap;

use rayon::prelude::*;
use serde::Serialize;
use synthgen_core::Pose;
use synthgen_formats::source::{FrameLocation, FrameSource};

pub use crate::data::pick_split;
use crate::data::Instance;
pub use crate::dataset_objects::load_eval_objects;
use crate::error::{Error, Result};
use crate::metrics::{EvalObject, PoseErrors, Rotations};
use crate::pose_model::{Objects, Prediction};
use crate::results::Estimate;

/// One annotated object instance.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GtInstance {
    pub scene_id: u32,
    pub im_id: u32,
    pub gt_id: usize,
    pub obj_id: u32,
    /// `cam_from_obj` with the nearest proper rotation.
    pub pose: Pose,
    /// `cam_from_obj` as the file stores it (metres): what bop_toolkit scores.
    pub stored: Pose,
    pub visib_fract: f64,
}

impl GtInstance {
    /// The pose the metrics use with `rotations`.
    pub fn pose_for(&self, rotations: Rotations) -> Pose {
        match rotations {
            Rotations::AsStored => self.stored,
            Rotations::Nearest => self.pose,
        }
    }
}

/// All GT instances of a split with `visib_fract >= min_visib_fract` (all of them when the
/// scene has no `scene_gt_info.json`).
pub fn read_gt(ds: &dyn FrameSource, split: &str, min_visib_fract: f64) -> Result<Vec<GtInstance>> {
    let mut out = Vec::new();
    for frame in ds.annotation_frames(&[split.to_string()])? {
        let FrameLocation {
            scene_id, im_id, ..
        } = frame.location;
        for (gt_id, g) in frame.gt.iter().enumerate() {
            let visib_fract = frame
                .gt_info
                .as_ref()
                .and_then(|v| v.get(gt_id))
                .map_or(1.0, |i| i.visib_fract);
            if visib_fract < min_visib_fract {
                continue;
            }
            out.push(GtInstance {
                scene_id,
                im_id,
                gt_id,
                obj_id: g.obj_id,
                pose: g.cam_from_obj(),
                stored: g.cam_from_obj_as_stored(),
                visib_fract,
            });
        }
    }
    Ok(out)
}

/// Scores of one object (or of all objects pooled).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct ObjectScores {
    /// GT instances.
    pub n_gt: usize,
    /// Estimates matched to a GT instance (the ones the mean errors average over).
    pub n_est: usize,
    /// Fraction of GT instances with an ADD(-S) error below 10% of the diameter.
    pub add_s_acc: f64,
    /// Mean ADD(-S) error of the estimates, millimetres (ADD-S for symmetric objects).
    pub mean_add_mm: Option<f64>,
    /// Fraction of GT instances within 5 cm and 5°.
    pub acc_5cm5deg: f64,
    pub mean_te_cm: Option<f64>,
    pub mean_re_deg: Option<f64>,
    /// Median translation and rotation errors of the estimates.
    pub median_te_cm: Option<f64>,
    pub median_re_deg: Option<f64>,
}

/// The median of `v` (the mean of the middle two for an even count); None when empty.
fn median(v: &[f64]) -> Option<f64> {
    let mut v = v.to_vec();
    v.sort_by(f64::total_cmp);
    let n = v.len();
    (n > 0).then(|| 0.5 * (v[(n - 1) / 2] + v[n / 2]))
}

#[derive(Default)]
struct Acc {
    n_gt: usize,
    n_est: usize,
    n_add_ok: usize,
    n_5cm5deg: usize,
    sum_add_m: f64,
    sum_te_m: f64,
    sum_re_deg: f64,
    te_m: Vec<f64>,
    re_deg: Vec<f64>,
}

impl Acc {
    fn scores(&self) -> ObjectScores {
        let mean = |s: f64| (self.n_est > 0).then(|| s / self.n_est as f64);
        let frac = |n: usize| {
            if self.n_gt == 0 {
                0.0
            } else {
                n as f64 / self.n_gt as f64
            }
        };
        ObjectScores {
            n_gt: self.n_gt,
            n_est: self.n_est,
            add_s_acc: frac(self.n_add_ok),
            mean_add_mm: mean(self.sum_add_m * 1000.0),
            acc_5cm5deg: frac(self.n_5cm5deg),
            mean_te_cm: mean(self.sum_te_m * 100.0),
            mean_re_deg: mean(self.sum_re_deg),
            median_te_cm: median(&self.te_m).map(|m| m * 100.0),
            median_re_deg: median(&self.re_deg),
        }
    }
}

/// A GT instance's matched estimate and its errors.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Match {
    pub gt: GtInstance,
    pub estimate: Option<(Estimate, PoseErrors)>,
}

/// The outcome of an evaluation.
#[derive(Debug, Clone, PartialEq)]
pub struct EvalReport {
    pub per_object: BTreeMap<u32, ObjectScores>,
    pub all: ObjectScores,
    pub matches: Vec<Match>,
    /// Estimates not used: for an (image, object) with no GT, or beyond its GT count.
    pub unmatched_estimates: usize,
}

/// Scores a model's predictions for `instances` (in the same order) against `gts`, as
/// `synthgen eval --checkpoint` does: each prediction becomes an estimate with its confidence
/// as score (RNet, which predicts no translation, gets the GT translation).
pub fn score_predictions<'a>(
    preds: &[Prediction],
    instances: impl IntoIterator<Item = &'a Instance>,
    gts: &[GtInstance],
    objects: &Objects,
    rotations: Rotations,
) -> Result<EvalReport> {
    evaluate(
        gts,
        &prediction_estimates(preds, instances),
        &eval_objects(objects),
        rotations,
    )
}

/// A model's predictions for `instances` (in the same order) as estimates: its confidence as
/// score; RNet, which predicts no translation, gets the GT translation.
pub fn prediction_estimates<'a>(
    preds: &[Prediction],
    instances: impl IntoIterator<Item = &'a Instance>,
) -> Vec<Estimate> {
    preds
        .iter()
        .zip(instances)
        .map(|(p, i)| {
            Estimate::new(
                i.scene_id,
                i.im_id,
                i.obj_id,
                p.score(),
                p.pose(i.pose.translation_m),
            )
        })
        .collect()
}

/// The metric side of training objects, by id.
pub fn eval_objects(objects: &Objects) -> BTreeMap<u32, EvalObject> {
    objects
        .iter()
        .map(|(&id, o)| (id, o.eval.clone()))
        .collect()
}

/// Matches estimates to GT per (scene, image, object) and scores them. For an (image,
/// object) with k GT instances the k highest-scoring estimates are used; in descending
/// score order each takes the free GT instance it fits best (lowest ADD(-S)). GT instances
/// left without an estimate count as wrong. `rotations` says which matrices the metrics use:
/// the files' as stored (bop_toolkit's way, the default) or the nearest proper rotations.
pub fn evaluate(
    gts: &[GtInstance],
    estimates: &[Estimate],
    objects: &BTreeMap<u32, EvalObject>,
    rotations: Rotations,
) -> Result<EvalReport> {
    type Key = (u32, u32, u32);
    let mut groups: BTreeMap<Key, (Vec<GtInstance>, Vec<Estimate>)> = BTreeMap::new();
    for g in gts {
        groups
            .entry((g.scene_id, g.im_id, g.obj_id))
            .or_default()
            .0
            .push(*g);
    }
    let mut unmatched = 0;
    for e in estimates {
        match groups.get_mut(&(e.scene_id, e.im_id, e.obj_id)) {
            Some(g) => g.1.push(*e),
            None => unmatched += 1,
        }
    }
    for obj_id in groups.keys().map(|k| k.2) {
        if !objects.contains_key(&obj_id) {
            return Err(Error::InvalidOption(format!(
                "no evaluation model for object {obj_id}"
            )));
        }
    }
    let per_group: Vec<(Vec<Match>, usize)> = groups
        .into_par_iter()
        .map(|((_, _, obj_id), (gts, mut ests))| {
            let obj = &objects[&obj_id];
            ests.sort_by(|a, b| b.score.total_cmp(&a.score));
            let extra = ests.len().saturating_sub(gts.len());
            ests.truncate(gts.len());
            let mut matches: Vec<Match> =
                gts.iter().map(|&gt| Match { gt, estimate: None }).collect();
            for e in ests {
                let best = matches
                    .iter()
                    .enumerate()
                    .filter(|(_, m)| m.estimate.is_none())
                    .map(|(i, m)| {
                        let err =
                            obj.scoring_errors(&m.gt.pose_for(rotations), &e.pose_for(rotations));
                        (i, err)
                    })
                    .min_by(|a, b| a.1.add_s_m.total_cmp(&b.1.add_s_m));
                if let Some((i, err)) = best {
                    matches[i].estimate = Some((e, err));
                }
            }
            (matches, extra)
        })
        .collect();

    let mut acc: BTreeMap<u32, Acc> = BTreeMap::new();
    let mut all = Acc::default();
    let mut matches = Vec::new();
    for (ms, extra) in per_group {
        unmatched += extra;
        for m in ms {
            let obj = &objects[&m.gt.obj_id];
            let a = acc.entry(m.gt.obj_id).or_default();
            for a in [a, &mut all] {
                a.n_gt += 1;
                if let Some((_, err)) = &m.estimate {
                    a.n_est += 1;
                    a.sum_add_m += err.add_s_m;
                    a.sum_te_m += err.te_m;
                    a.sum_re_deg += err.re_deg;
                    a.te_m.push(err.te_m);
                    a.re_deg.push(err.re_deg);
                    a.n_add_ok += usize::from(obj.add_s_correct(err));
                    a.n_5cm5deg += usize::from(err.within_5cm5deg());
                }
            }
            matches.push(m);
        }
    }
    Ok(EvalReport {
        per_object: acc.iter().map(|(&k, a)| (k, a.scores())).collect(),
        all: all.scores(),
        matches,
        unmatched_estimates: unmatched,
    })
}

fn opt(v: Option<f64>, digits: usize) -> String {
    v.map_or("–".to_string(), |v| format!("{v:.digits$}"))
}

impl EvalReport {
    /// The per-object table in markdown, with an `all` row.
    pub fn to_markdown(&self, objects: &BTreeMap<u32, EvalObject>) -> String {
        let mut s = String::from(
            "| object | metric | n_gt | n_est | ADD(-S) acc | mean ADD(-S) mm | 5cm5° acc | mean te cm | mean re ° |\n\
             |---|---|---:|---:|---:|---:|---:|---:|---:|\n",
        );
        let row = |name: String, metric: &str, r: &ObjectScores| {
            format!(
                "| {name} | {metric} | {} | {} | {:.1}% | {} | {:.1}% | {} | {} |\n",
                r.n_gt,
                r.n_est,
                100.0 * r.add_s_acc,
                opt(r.mean_add_mm, 1),
                100.0 * r.acc_5cm5deg,
                opt(r.mean_te_cm, 2),
                opt(r.mean_re_deg, 2)
            )
        };
        for (id, r) in &self.per_object {
            let metric = if objects.get(id).is_some_and(|o| o.symmetric) {
                "ADD-S"
            } else {
                "ADD"
            };
            s += &row(format!("{id}"), metric, r);
        }
        s += &row("all".into(), "", &self.all);
        s
    }

    /// `{"<obj_id>": scores, ..., "all": scores}`; means with no estimate are `null`.
    pub fn to_json(&self) -> serde_json::Value {
        let mut m = serde_json::Map::new();
        for (id, r) in &self.per_object {
            m.insert(id.to_string(), serde_json::json!(r));
        }
        m.insert("all".into(), serde_json::json!(self.all));
        serde_json::Value::Object(m)
    }
}

/// [`evaluate`] of each scene's GT instances and estimates on their own, by scene id (the
/// scenes of `gts`).
pub fn evaluate_per_scene(
    gts: &[GtInstance],
    estimates: &[Estimate],
    objects: &BTreeMap<u32, EvalObject>,
    rotations: Rotations,
) -> Result<BTreeMap<u32, EvalReport>> {
    let scenes: std::collections::BTreeSet<u32> = gts.iter().map(|g| g.scene_id).collect();
    scenes
        .into_iter()
        .map(|sc| {
            let g: Vec<GtInstance> = gts.iter().filter(|g| g.scene_id == sc).copied().collect();
            let e: Vec<Estimate> = estimates
                .iter()
                .filter(|e| e.scene_id == sc)
                .cloned()
                .collect();
            Ok((sc, evaluate(&g, &e, objects, rotations)?))
        })
        .collect()
}

/// The largest error of the ADD-S AUC, metres (PoseCNN's and DenseFusion's 10 cm).
pub const AUC_MAX_M: f64 = 0.1;

/// The area under the accuracy-threshold curve of `errors_m` (one error per GT instance, a
/// miss as +∞) for thresholds from 0 to `max_m`, in percent, as the YCB-Video toolbox of
/// PoseCNN and DenseFusion computes it (`VOCap` in `evaluate_poses_keyframe.m`): errors above
/// `max_m` count as misses, the accuracy at each sorted error is the share of GT instances at
/// or below it, each interval between consecutive errors (from 0, and on to `max_m`) counts at
/// the accuracy of its right end, and the area is divided by `max_m`. None for no GT instance.
pub fn auc_percent(errors_m: &[f64], max_m: f64) -> Option<f64> {
    let n = errors_m.len();
    if n == 0 {
        return None;
    }
    let mut d: Vec<f64> = errors_m
        .iter()
        .copied()
        .filter(|e| e.is_finite() && *e <= max_m)
        .collect();
    d.sort_by(f64::total_cmp);
    if d.is_empty() {
        return Some(0.0);
    }
    // mrec = [0, d.., max], mpre = [0, (1..=k)/n, k/n] (already non-decreasing).
    let mut rec = Vec::with_capacity(d.len() + 2);
    rec.push(0.0);
    rec.extend_from_slice(&d);
    rec.push(max_m);
    let k = d.len();
    let pre = |i: usize| -> f64 {
        match i {
            0 => 0.0,
            i if i <= k => i as f64 / n as f64,
            _ => k as f64 / n as f64,
        }
    };
    let area: f64 = (1..rec.len())
        .filter(|&i| rec[i] != rec[i - 1])
        .map(|i| (rec[i] - rec[i - 1]) * pre(i))
        .sum();
    Some(100.0 * area / max_m)
}

/// ADD-S AUC (up to [`AUC_MAX_M`], percent) of an evaluation, overall, per object and per
/// scene: every GT instance with ADD-S (the closest-point distance) for every object, as
/// PoseCNN and DenseFusion report it on YCB-Video; a GT instance without an estimate is a miss.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct AucScores {
    pub all: Option<f64>,
    pub per_object: BTreeMap<u32, f64>,
    pub per_scene: BTreeMap<u32, f64>,
}

impl EvalReport {
    /// The ADD-S AUC of the matches (see [`AucScores`]), with the poses `rotations` says.
    pub fn add_s_auc(
        &self,
        objects: &BTreeMap<u32, EvalObject>,
        rotations: Rotations,
    ) -> AucScores {
        let errors: Vec<(u32, u32, f64)> = self
            .matches
            .par_iter()
            .map(|m| {
                let e = match (&m.estimate, objects.get(&m.gt.obj_id)) {
                    (Some((est, _)), Some(obj)) => crate::metrics::adi(
                        &obj.points_m,
                        &m.gt.pose_for(rotations),
                        &est.pose_for(rotations),
                    ),
                    _ => f64::INFINITY,
                };
                (m.gt.obj_id, m.gt.scene_id, e)
            })
            .collect();
        let group = |key: fn(&(u32, u32, f64)) -> u32| {
            let mut by: BTreeMap<u32, Vec<f64>> = BTreeMap::new();
            for e in &errors {
                by.entry(key(e)).or_default().push(e.2);
            }
            by.into_iter()
                .filter_map(|(k, v)| Some((k, auc_percent(&v, AUC_MAX_M)?)))
                .collect()
        };
        AucScores {
            all: auc_percent(&errors.iter().map(|e| e.2).collect::<Vec<_>>(), AUC_MAX_M),
            per_object: group(|e| e.0),
            per_scene: group(|e| e.1),
        }
    }
}

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::expect_used)]
mod tests {
    use super::*;
    use synthgen_core::glam::{DMat3, DVec3};

    fn gt(im_id: u32, obj_id: u32, t: [f64; 3]) -> GtInstance {
        GtInstance {
            scene_id: 0,
            im_id,
            gt_id: 0,
            obj_id,
            pose: Pose::new(DMat3::IDENTITY, DVec3::from_array(t)),
            stored: Pose::new(DMat3::IDENTITY, DVec3::from_array(t)),
            visib_fract: 1.0,
        }
    }

    fn est(im_id: u32, obj_id: u32, score: f64, t: [f64; 3]) -> Estimate {
        Estimate::new(
            0,
            im_id,
            obj_id,
            score,
            Pose::new(DMat3::IDENTITY, DVec3::from_array(t)),
        )
    }

    fn objects() -> BTreeMap<u32, EvalObject> {
        let pts = vec![DVec3::new(0.05, 0.0, 0.0), DVec3::new(-0.05, 0.0, 0.0)];
        BTreeMap::from([(
            1,
            EvalObject {
                points_m: pts,
                diameter_m: 0.1,
                symmetric: false,
            },
        )])
    }

    #[test]
    fn auc_is_the_area_under_the_accuracy_curve_as_the_ycb_toolbox_computes_it() {
        // Every error 0: accuracy 1 over the whole range.
        assert_eq!(auc_percent(&[0.0, 0.0], 0.1), Some(100.0));
        // Nothing within 10 cm (or a miss): 0.
        assert_eq!(auc_percent(&[0.2, f64::INFINITY], 0.1), Some(0.0));
        assert_eq!(auc_percent(&[], 0.1), None);
        // One of two at 2 cm, the other missed: each interval counts at the accuracy of its
        // right end (the toolbox's step), so 0.5 from 0 to 10 cm = 50 %.
        let a = auc_percent(&[0.02, f64::INFINITY], 0.1).unwrap();
        assert!((a - 50.0).abs() < 1e-9, "{a}");
        // Errors 1, 3, 5 cm of 4 GT: steps (1-0)*1/4 + (3-1)*2/4 + (5-3)*3/4 + (10-5)*3/4
        // = 0.25 + 1 + 1.5 + 3.75 = 6.5 cm of 10: 65 %; the order of the errors is irrelevant.
        let a = auc_percent(&[0.05, 0.01, f64::NAN, 0.03], 0.1).unwrap();
        assert!((a - 65.0).abs() < 1e-9, "{a}");
    }

    #[test]
    fn add_s_auc_counts_misses_and_groups_by_object_and_scene() {
        let mut g_other_scene = gt(1, 1, [0.0, 0.0, 1.0]);
        g_other_scene.scene_id = 3;
        let gts = [gt(0, 1, [0.0, 0.0, 1.0]), g_other_scene];
        // Scene 0's estimate 2 cm off along x (ADD-S of the two points ±5 cm: 2 cm); scene
        // 3's image has none.
        let ests = [est(0, 1, 1.0, [0.02, 0.0, 1.0])];
        let r = evaluate(&gts, &ests, &objects(), Rotations::AsStored).unwrap();
        let auc = r.add_s_auc(&objects(), Rotations::AsStored);
        assert!((auc.all.unwrap() - 50.0).abs() < 1e-9, "{auc:?}");
        assert!((auc.per_object[&1] - 50.0).abs() < 1e-9);
        assert!((auc.per_scene[&0] - 100.0).abs() < 1e-9, "{auc:?}");
        assert_eq!(auc.per_scene[&3], 0.0);
    }

    #[test]
    fn missing_estimate_counts_as_wrong_and_highest_score_counts() {
        let gts = [gt(0, 1, [0.0, 0.0, 1.0]), gt(1, 1, [0.0, 0.0, 1.0])];
        let ests = [
            // Image 0: the better estimate has the lower score, so the worse one counts.
            est(0, 1, 0.9, [0.02, 0.0, 1.0]),
            est(0, 1, 0.1, [0.0, 0.0, 1.0]),
            // An estimate for an image without GT is ignored.
            est(5, 1, 1.0, [0.0, 0.0, 1.0]),
        ];
        let r = evaluate(&gts, &ests, &objects(), Rotations::AsStored).unwrap();
        let s = r.per_object[&1];
        assert_eq!((s.n_gt, s.n_est), (2, 1));
        // 2 cm > 10% of 10 cm: wrong; image 1 has no estimate: wrong.
        assert_eq!(s.add_s_acc, 0.0);
        assert!((s.mean_add_mm.unwrap() - 20.0).abs() < 1e-9);
        assert!((s.mean_te_cm.unwrap() - 2.0).abs() < 1e-9);
        // 2 cm < 5 cm, 0°: 1 of 2 GT instances.
        assert_eq!(s.acc_5cm5deg, 0.5);
        assert_eq!(r.unmatched_estimates, 2);
        assert_eq!(r.all, s);
        let md = r.to_markdown(&objects());
        assert!(
            md.contains("| 1 | ADD | 2 | 1 | 0.0% | 20.0 | 50.0% | 2.00 | 0.00 |"),
            "{md}"
        );
        let j = r.to_json();
        assert_eq!(j["all"]["n_gt"], 2);
        assert_eq!(j["1"]["acc_5cm5deg"], 0.5);
    }

    #[test]
    fn two_instances_match_their_nearest_estimates() {
        let mut g2 = gt(0, 1, [0.3, 0.0, 1.0]);
        g2.gt_id = 1;
        let gts = [gt(0, 1, [0.0, 0.0, 1.0]), g2];
        let ests = [
            est(0, 1, 0.5, [0.301, 0.0, 1.0]),
            est(0, 1, 0.4, [0.001, 0.0, 1.0]),
        ];
        let r = evaluate(&gts, &ests, &objects(), Rotations::AsStored).unwrap();
        assert_eq!(r.all.add_s_acc, 1.0);
        assert!((r.all.mean_add_mm.unwrap() - 1.0).abs() < 1e-9);
    }
}
