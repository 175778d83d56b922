//! COCO's detection scores as pycocotools' `COCOeval` computes them, which is how
//! bop_toolkit's `scripts/eval_bop22_coco.py` scores BOP's 2D detection and segmentation
//! tasks: AP over IoU 0.50:0.95, AP50, AP75, AP and AR by object size, AR at 1, 10 and 100
//! detections, for boxes (`bbox`) or masks (`segm`).
//!
//! The rules followed to the letter, because a different rule gives a different number:
//! - per (image, object), detections best score first (ties in file order), at most 100;
//!   greedy matching at each IoU threshold, a GT taken once, crowd GT reusable;
//! - a GT is ignored only for `iscrowd` (pycocotools' `_prepare` overwrites the `ignore`
//!   field that bop_toolkit's `calc_gt_coco.py` writes for instances less than 10 % visible,
//!   so those instances are scored as any other) or for its area outside the size range;
//!   the size of a GT is its `area` (visible pixels), of a detection with a box its box's
//!   width x height (pycocotools' `loadRes` reads the box first, also for `segm`);
//! - precision made monotone and read at 101 recall points; an object with no GT counts
//!   in no mean; AR is the recall at the last detection, averaged the same way.

use std::collections::BTreeMap;

use synthgen_formats::coco::Rle;

/// What is compared: boxes or masks.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum IouType {
    Bbox,
    Segm,
}

impl IouType {
    pub fn name(self) -> &'static str {
        match self {
            IouType::Bbox => "bbox",
            IouType::Segm => "segm",
        }
    }
}

/// One ground-truth instance.
#[derive(Debug, Clone)]
pub struct GtInstance {
    /// Index of its image in the evaluated images.
    pub image: usize,
    pub category: u32,
    /// `[x, y, width, height]`, COCO's (the object covers `x..x + width`).
    pub bbox: [f64; 4],
    /// Visible pixels (the size ranges read it).
    pub area: f64,
    pub iscrowd: bool,
    /// The visible mask (needed for `segm`).
    pub segmentation: Option<Rle>,
}

/// One detection.
#[derive(Debug, Clone)]
pub struct DtInstance {
    pub image: usize,
    pub category: u32,
    pub score: f64,
    pub bbox: [f64; 4],
    /// Its size for the size ranges (pycocotools: the box's width x height).
    pub area: f64,
    pub segmentation: Option<Rle>,
}

/// The twelve numbers `COCOeval.summarize` prints, in its order, and each object's.
#[derive(Debug, Clone, PartialEq)]
pub struct CocoScores {
    pub iou_type: IouType,
    /// AP, AP50, AP75, AP_small, AP_medium, AP_large, AR1, AR10, AR100, AR_small,
    /// AR_medium, AR_large (−1 where nothing could be scored, as pycocotools gives).
    pub stats: [f64; 12],
    /// Per object with GT: AP, AP50, AP75 and AR100 over all sizes, and its GT count.
    pub objects: BTreeMap<u32, ObjectScores>,
}

/// One object's scores.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ObjectScores {
    pub ap: f64,
    pub ap50: f64,
    pub ap75: f64,
    pub ar100: f64,
    pub n_gt: usize,
}

/// bop_toolkit's names of [`CocoScores::stats`] (its `scores_bop22_coco_*.json` keys).
pub const STAT_NAMES: [&str; 12] = [
    "AP",
    "AP50",
    "AP75",
    "AP_small",
    "AP_medium",
    "AP_large",
    "AR1",
    "AR10",
    "AR100",
    "AR_small",
    "AR_medium",
    "AR_large",
];

const MAX_DETS: [usize; 3] = [1, 10, 100];
const AREA_RANGES: [[f64; 2]; 4] = [
    [0.0, 1e10],
    [0.0, 32.0 * 32.0],
    [32.0 * 32.0, 96.0 * 96.0],
    [96.0 * 96.0, 1e10],
];

/// `np.linspace(.5, .95, 10)`, value for value.
fn iou_thresholds() -> [f64; 10] {
    let step = (0.95f64 - 0.5) / 9.0;
    let mut t = [0.0; 10];
    for (i, v) in t.iter_mut().enumerate() {
        *v = i as f64 * step + 0.5;
    }
    t[9] = 0.95;
    t
}

/// `np.linspace(0, 1, 101)`, value for value.
fn recall_thresholds() -> [f64; 101] {
    let mut r = [0.0; 101];
    for (i, v) in r.iter_mut().enumerate() {
        *v = i as f64 * 0.01;
    }
    r[100] = 1.0;
    r
}

/// pycocotools' `bbIou` of a detection's and a GT's box.
fn box_iou(d: [f64; 4], g: [f64; 4], crowd: bool) -> f64 {
    let w = (d[0] + d[2]).min(g[0] + g[2]) - d[0].max(g[0]);
    if w <= 0.0 {
        return 0.0;
    }
    let h = (d[1] + d[3]).min(g[1] + g[3]) - d[1].max(g[1]);
    if h <= 0.0 {
        return 0.0;
    }
    let i = w * h;
    let u = if crowd {
        d[2] * d[3]
    } else {
        d[2] * d[3] + g[2] * g[3] - i
    };
    i / u
}

/// pycocotools' `rleIou`: the boxes first, the pixels where they overlap.
fn mask_iou(d: &Rle, g: &Rle, crowd: bool) -> f64 {
    if box_iou(d.bbox(), g.bbox(), crowd) <= 0.0 {
        return 0.0;
    }
    let i = d.intersection(g) as f64;
    let (da, ga) = (d.area() as f64, g.area() as f64);
    let u = if crowd { da } else { da + ga - i };
    i / u
}

/// One (image, object): its GT, its detections (best first, at most 100) and their IoUs
/// (per detection, per GT; empty when either is).
type ImagePairs = (Vec<usize>, Vec<usize>, Vec<Vec<f64>>);

/// One (image, object, size range) as `evaluateImg` leaves it.
struct ImageEval {
    /// Per threshold, per detection (best first, at most 100): matched?
    dt_matched: Vec<Vec<bool>>,
    dt_ignored: Vec<Vec<bool>>,
    dt_scores: Vec<f64>,
    gt_ignored: Vec<bool>,
}

/// Scores `dts` against `gts` over `n_images` images as `COCOeval` (evaluate, accumulate,
/// summarize) does. With `segm`, every instance needs its mask: an error names the first
/// that has none.
pub fn evaluate(
    gts: &[GtInstance],
    dts: &[DtInstance],
    n_images: usize,
    iou_type: IouType,
) -> Result<CocoScores, String> {
    if iou_type == IouType::Segm {
        if let Some(i) = gts.iter().position(|g| g.segmentation.is_none()) {
            return Err(format!("GT instance {i} has no mask to score masks with"));
        }
        if let Some(i) = dts.iter().position(|d| d.segmentation.is_none()) {
            return Err(format!(
                "detection {i} has no \"segmentation\" (segm scores need every detection's mask)"
            ));
        }
    }
    let thresholds = iou_thresholds();
    let rec_thrs = recall_thresholds();
    let mut categories: Vec<u32> = gts.iter().map(|g| g.category).collect();
    categories.sort_unstable();
    categories.dedup();

    // Per (image, category): the GT and the detections in file order.
    let mut gt_of: BTreeMap<(usize, u32), Vec<usize>> = BTreeMap::new();
    for (i, g) in gts.iter().enumerate() {
        gt_of.entry((g.image, g.category)).or_default().push(i);
    }
    let mut dt_of: BTreeMap<(usize, u32), Vec<usize>> = BTreeMap::new();
    for (i, d) in dts.iter().enumerate() {
        if d.image < n_images {
            dt_of.entry((d.image, d.category)).or_default().push(i);
        }
    }

    let t_n = thresholds.len();
    let (k_n, a_n, m_n, r_n) = (
        categories.len(),
        AREA_RANGES.len(),
        MAX_DETS.len(),
        rec_thrs.len(),
    );
    // precision[t][r][k][a][m], recall[t][k][a][m], −1 where not scored.
    let pidx = |t: usize, r: usize, k: usize, a: usize, m: usize| {
        (((t * r_n + r) * k_n + k) * a_n + a) * m_n + m
    };
    let ridx = |t: usize, k: usize, a: usize, m: usize| ((t * k_n + k) * a_n + a) * m_n + m;
    let mut precision = vec![-1.0f64; t_n * r_n * k_n * a_n * m_n];
    let mut recall = vec![-1.0f64; t_n * k_n * a_n * m_n];
    let empty: Vec<usize> = Vec::new();

    for (k, &cat) in categories.iter().enumerate() {
        // The IoUs per image: detections best first (stable), at most 100, by GT in order.
        let mut per_image: Vec<Option<ImagePairs>> = Vec::with_capacity(n_images);
        for img in 0..n_images {
            let g = gt_of.get(&(img, cat)).unwrap_or(&empty);
            let mut d = dt_of.get(&(img, cat)).unwrap_or(&empty).clone();
            if g.is_empty() && d.is_empty() {
                per_image.push(None);
                continue;
            }
            d.sort_by(|&a, &b| dts[b].score.total_cmp(&dts[a].score));
            d.truncate(MAX_DETS[2]);
            let ious: Vec<Vec<f64>> = if g.is_empty() || d.is_empty() {
                Vec::new()
            } else {
                d.iter()
                    .map(|&di| {
                        g.iter()
                            .map(|&gi| {
                                let (dd, gg) = (&dts[di], &gts[gi]);
                                match (iou_type, &dd.segmentation, &gg.segmentation) {
                                    (IouType::Segm, Some(ds), Some(gs)) => {
                                        mask_iou(ds, gs, gg.iscrowd)
                                    }
                                    _ => box_iou(dd.bbox, gg.bbox, gg.iscrowd),
                                }
                            })
                            .collect()
                    })
                    .collect()
            };
            per_image.push(Some((g.clone(), d, ious)));
        }

        for (a, range) in AREA_RANGES.iter().enumerate() {
            let outside = |area: f64| area < range[0] || area > range[1];
            let evals: Vec<ImageEval> = per_image
                .iter()
                .flatten()
                .map(|(g, d, ious)| {
                    // GT not ignored first (stable).
                    let ignored: Vec<bool> = g
                        .iter()
                        .map(|&gi| gts[gi].iscrowd || outside(gts[gi].area))
                        .collect();
                    let mut order: Vec<usize> = (0..g.len()).collect();
                    order.sort_by_key(|&j| ignored[j]);
                    let gt_ig: Vec<bool> = order.iter().map(|&j| ignored[j]).collect();
                    let crowd: Vec<bool> = order.iter().map(|&j| gts[g[j]].iscrowd).collect();
                    let mut dt_m = vec![vec![false; d.len()]; t_n];
                    let mut dt_ig = vec![vec![false; d.len()]; t_n];
                    if !ious.is_empty() {
                        for (t, &thr) in thresholds.iter().enumerate() {
                            let mut gt_taken = vec![false; g.len()];
                            for di in 0..d.len() {
                                let mut best = thr.min(1.0 - 1e-10);
                                let mut m: Option<usize> = None;
                                for (gpos, &gj) in order.iter().enumerate() {
                                    if gt_taken[gpos] && !crowd[gpos] {
                                        continue;
                                    }
                                    if let Some(mm) = m {
                                        if !gt_ig[mm] && gt_ig[gpos] {
                                            break;
                                        }
                                    }
                                    let v = ious[di][gj];
                                    if v < best {
                                        continue;
                                    }
                                    best = v;
                                    m = Some(gpos);
                                }
                                if let Some(mm) = m {
                                    dt_ig[t][di] = gt_ig[mm];
                                    dt_m[t][di] = true;
                                    gt_taken[mm] = true;
                                }
                            }
                        }
                    }
                    for (di, &dj) in d.iter().enumerate() {
                        if outside(dts[dj].area) {
                            for t in 0..t_n {
                                if !dt_m[t][di] {
                                    dt_ig[t][di] = true;
                                }
                            }
                        }
                    }
                    ImageEval {
                        dt_matched: dt_m,
                        dt_ignored: dt_ig,
                        dt_scores: d.iter().map(|&dj| dts[dj].score).collect(),
                        gt_ignored: gt_ig,
                    }
                })
                .collect();
            if evals.is_empty() {
                continue;
            }
            let npig = evals
                .iter()
                .flat_map(|e| e.gt_ignored.iter())
                .filter(|&&ig| !ig)
                .count();
            for (m, &max_det) in MAX_DETS.iter().enumerate() {
                // Every image's first max_det detections, best first over the images
                // (stable: image order, then each image's order).
                let mut entries: Vec<(usize, usize)> = Vec::new();
                for (e_i, e) in evals.iter().enumerate() {
                    for di in 0..e.dt_scores.len().min(max_det) {
                        entries.push((e_i, di));
                    }
                }
                entries.sort_by(|x, y| {
                    evals[y.0].dt_scores[y.1].total_cmp(&evals[x.0].dt_scores[x.1])
                });
                if npig == 0 {
                    continue;
                }
                for t in 0..t_n {
                    let (mut tp, mut fp) = (0.0f64, 0.0f64);
                    let mut rc = Vec::with_capacity(entries.len());
                    let mut pr = Vec::with_capacity(entries.len());
                    for &(e_i, di) in &entries {
                        let (matched, ignored) =
                            (evals[e_i].dt_matched[t][di], evals[e_i].dt_ignored[t][di]);
                        if !ignored {
                            if matched {
                                tp += 1.0;
                            } else {
                                fp += 1.0;
                            }
                        }
                        rc.push(tp / npig as f64);
                        pr.push(tp / (fp + tp + f64::EPSILON));
                    }
                    recall[ridx(t, k, a, m)] = rc.last().copied().unwrap_or(0.0);
                    for i in (1..pr.len()).rev() {
                        if pr[i] > pr[i - 1] {
                            pr[i - 1] = pr[i];
                        }
                    }
                    for (r, &thr) in rec_thrs.iter().enumerate() {
                        // searchsorted(rc, thr, side='left'); past the end: 0 from here on.
                        let pi = rc.partition_point(|&v| v < thr);
                        precision[pidx(t, r, k, a, m)] = pr.get(pi).copied().unwrap_or(0.0);
                    }
                }
            }
        }
    }

    // summarize: the mean over the entries > −1.
    let mean = |values: &mut dyn Iterator<Item = f64>| {
        let (mut s, mut n) = (0.0, 0usize);
        for v in values.filter(|&v| v > -1.0) {
            s += v;
            n += 1;
        }
        if n == 0 {
            -1.0
        } else {
            s / n as f64
        }
    };
    let ts_all: Vec<usize> = (0..t_n).collect();
    let ap = |ts: &[usize], ks: &[usize], a: usize, m: usize| {
        mean(
            &mut ts
                .iter()
                .flat_map(|&t| (0..r_n).flat_map(move |r| ks.iter().map(move |&k| (t, r, k))))
                .map(|(t, r, k)| precision[pidx(t, r, k, a, m)]),
        )
    };
    let ar = |ks: &[usize], a: usize, m: usize| {
        mean(
            &mut ts_all
                .iter()
                .flat_map(|&t| ks.iter().map(move |&k| (t, k)))
                .map(|(t, k)| recall[ridx(t, k, a, m)]),
        )
    };
    let ks_all: Vec<usize> = (0..k_n).collect();
    let (i50, i75) = (0usize, 5usize);
    let stats = [
        ap(&ts_all, &ks_all, 0, 2),
        ap(&[i50], &ks_all, 0, 2),
        ap(&[i75], &ks_all, 0, 2),
        ap(&ts_all, &ks_all, 1, 2),
        ap(&ts_all, &ks_all, 2, 2),
        ap(&ts_all, &ks_all, 3, 2),
        ar(&ks_all, 0, 0),
        ar(&ks_all, 0, 1),
        ar(&ks_all, 0, 2),
        ar(&ks_all, 1, 2),
        ar(&ks_all, 2, 2),
        ar(&ks_all, 3, 2),
    ];
    let mut objects = BTreeMap::new();
    for (k, &cat) in categories.iter().enumerate() {
        objects.insert(
            cat,
            ObjectScores {
                ap: ap(&ts_all, &[k], 0, 2),
                ap50: ap(&[i50], &[k], 0, 2),
                ap75: ap(&[i75], &[k], 0, 2),
                ar100: ar(&[k], 0, 2),
                n_gt: gts.iter().filter(|g| g.category == cat).count(),
            },
        );
    }
    Ok(CocoScores {
        iou_type,
        stats,
        objects,
    })
}

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::expect_used)]
mod tests {
    use super::*;

    /// pycocotools' precision is tp / (tp + fp + eps): a perfect score is 1 − 2e-16.
    fn near(a: f64, b: f64) -> bool {
        (a - b).abs() < 1e-12
    }

    fn gt(image: usize, category: u32, bbox: [f64; 4]) -> GtInstance {
        GtInstance {
            image,
            category,
            bbox,
            area: bbox[2] * bbox[3],
            iscrowd: false,
            segmentation: None,
        }
    }

    fn dt(image: usize, category: u32, score: f64, bbox: [f64; 4]) -> DtInstance {
        DtInstance {
            image,
            category,
            score,
            bbox,
            area: bbox[2] * bbox[3],
            segmentation: None,
        }
    }

    #[test]
    fn thresholds_are_numpys() {
        let t = iou_thresholds();
        assert_eq!(t[0], 0.5);
        assert_eq!(t[5], 0.75);
        assert_eq!(t[9], 0.95);
        let r = recall_thresholds();
        assert_eq!((r[0], r[50], r[100]), (0.0, 0.5, 1.0));
    }

    #[test]
    fn perfect_detections_score_one_and_misses_lower_recall() {
        let gts = vec![
            gt(0, 1, [10.0, 10.0, 50.0, 50.0]),
            gt(1, 1, [20.0, 20.0, 40.0, 40.0]),
            gt(1, 2, [100.0, 100.0, 120.0, 100.0]),
        ];
        let dts: Vec<DtInstance> = gts
            .iter()
            .enumerate()
            .map(|(i, g)| dt(g.image, g.category, 0.9 - i as f64 * 0.1, g.bbox))
            .collect();
        let s = evaluate(&gts, &dts, 2, IouType::Bbox).unwrap();
        assert!(near(s.stats[0], 1.0), "{}", s.stats[0]);
        assert!(near(s.stats[1], 1.0), "{}", s.stats[1]);
        assert!(near(s.stats[8], 1.0), "{}", s.stats[8]);
        // No GT is small (< 32²): −1, as pycocotools prints.
        assert_eq!(s.stats[3], -1.0);
        assert_eq!(s.objects[&2].n_gt, 1);

        // Object 2 missed: its AP and recall are 0, the mean over objects halves.
        let s = evaluate(&gts, &dts[..2], 2, IouType::Bbox).unwrap();
        assert!(near(s.objects[&1].ap, 1.0), "{}", s.objects[&1].ap);
        assert_eq!(s.objects[&2].ap, 0.0);
        assert!(near(s.stats[0], 0.5), "{}", s.stats[0]);
        assert!(near(s.stats[8], 0.5), "{}", s.stats[8]);
    }

    #[test]
    fn a_false_positive_ranked_first_costs_precision() {
        // One GT; a wrong box scored above the right one: precision 1/2 at recall 1.
        let gts = vec![gt(0, 1, [0.0, 0.0, 100.0, 100.0])];
        let dts = vec![
            dt(0, 1, 0.9, [300.0, 300.0, 100.0, 100.0]),
            dt(0, 1, 0.8, [0.0, 0.0, 100.0, 100.0]),
        ];
        let s = evaluate(&gts, &dts, 1, IouType::Bbox).unwrap();
        assert!((s.stats[1] - 0.5).abs() < 1e-12, "{:?}", s.stats);
        // At one detection per image only the false positive is seen.
        assert_eq!(s.stats[6], 0.0);
        assert!(near(s.stats[8], 1.0), "{}", s.stats[8]);
        // A box at IoU 0.62 counts at 0.50..0.60 only: 3 of 10 thresholds.
        let dts = vec![dt(0, 1, 0.9, [0.0, 0.0, 100.0, 62.0])];
        let s = evaluate(&gts, &dts, 1, IouType::Bbox).unwrap();
        assert!((s.stats[0] - 0.3).abs() < 1e-12, "{:?}", s.stats);
        assert_eq!(s.stats[2], 0.0);
    }

    #[test]
    fn masks_are_scored_by_their_pixels() {
        let (w, h) = (8u32, 6u32);
        let mut a = vec![0u8; 48];
        let mut b = vec![0u8; 48];
        for y in 1..5 {
            for x in 1..5 {
                a[y * 8 + x] = 1;
            }
            for x in 2..5 {
                b[y * 8 + x] = 1;
            }
        }
        let ra = Rle::from_mask(&a, w, h);
        let rb = Rle::from_mask(&b, w, h);
        assert!((mask_iou(&rb, &ra, false) - 12.0 / 16.0).abs() < 1e-12);
        let g = GtInstance {
            segmentation: Some(ra),
            ..gt(0, 3, [1.0, 1.0, 4.0, 4.0])
        };
        let d = DtInstance {
            segmentation: Some(rb),
            ..dt(0, 3, 0.5, [1.0, 1.0, 4.0, 4.0])
        };
        // The boxes agree exactly, the masks at IoU 0.75: thresholds 0.50..0.75 count.
        let boxes = evaluate(
            std::slice::from_ref(&g),
            std::slice::from_ref(&d),
            1,
            IouType::Bbox,
        )
        .unwrap();
        assert!(near(boxes.stats[0], 1.0), "{}", boxes.stats[0]);
        let masks = evaluate(
            std::slice::from_ref(&g),
            std::slice::from_ref(&d),
            1,
            IouType::Segm,
        )
        .unwrap();
        assert!((masks.stats[0] - 0.6).abs() < 1e-12, "{:?}", masks.stats);
        let bare = DtInstance {
            segmentation: None,
            ..d
        };
        let e = evaluate(&[g], &[bare], 1, IouType::Segm).unwrap_err();
        assert!(e.contains("detection 0"), "{e}");
    }

    #[test]
    fn crowd_gt_absorbs_detections_without_counting() {
        let crowd = GtInstance {
            iscrowd: true,
            ..gt(0, 1, [0.0, 0.0, 200.0, 200.0])
        };
        let gts = vec![gt(0, 1, [0.0, 0.0, 50.0, 50.0]), crowd];
        let dts = vec![
            dt(0, 1, 0.9, [0.0, 0.0, 50.0, 50.0]),
            dt(0, 1, 0.8, [100.0, 100.0, 50.0, 50.0]),
            dt(0, 1, 0.7, [120.0, 100.0, 50.0, 50.0]),
        ];
        // The two boxes inside the crowd region are ignored, not false positives.
        let s = evaluate(&gts, &dts, 1, IouType::Bbox).unwrap();
        assert!(near(s.stats[0], 1.0), "{}", s.stats[0]);
    }
}
