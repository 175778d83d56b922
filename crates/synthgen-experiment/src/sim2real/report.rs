//! `report.md`, `report.json` and `plot.png` of `experiment sim2real`.

use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::Path;

use anyhow::Result;
use serde::{Deserialize, Serialize};
use synthgen_formats::draw::Canvas;
use synthgen_formats::io::atomic_write;

use super::detect::DetectorRecord;
use super::rows::{Metrics, NoGtRecord, RowRecord, NAIVE, NAIVE_ICP};
use super::{Settings, REAL_ONLY};

/// The row whose numbers are the result (`all`, `objects`); the others are baselines.
pub const MAIN_ROW: &str = "synth_fitted";

/// Seconds each step took when it was computed (kept in `timing.json`, so that a resumed
/// run still reports them), and this run's wall time.
#[derive(Debug, Clone, Default, Serialize, Deserialize)]
pub struct Timing {
    pub fit_s: f64,
    /// Per rendered set.
    pub render_s: BTreeMap<String, f64>,
    /// Per row: training (with loading) and scoring.
    #[serde(default)]
    pub rows_s: BTreeMap<String, f64>,
    /// The fits, renders and rows together, whenever they were computed.
    #[serde(default)]
    pub steps_total_s: f64,
    /// This invocation.
    #[serde(default)]
    pub this_run_s: f64,
}

#[derive(Debug, Clone, Serialize)]
pub struct Baseline {
    pub all: Metrics,
    pub objects: BTreeMap<String, Metrics>,
}

/// The result beside the naive centroid on the same instances: mean centre error, cm.
#[derive(Debug, Clone, Serialize)]
pub struct VsNaive {
    pub n: usize,
    pub model_cm: f64,
    pub naive_cm: f64,
}

/// `report.json`: the schema scripts depend on (`all`, `objects`, `scenes`, `baselines`,
/// `vs_naive`, `skipped_frames`), then the rows in full, the settings and the timing.
#[derive(Debug, Clone, Serialize)]
pub struct Report {
    pub all: Option<Metrics>,
    pub objects: BTreeMap<String, Metrics>,
    /// The result per test scene.
    pub scenes: BTreeMap<String, Metrics>,
    pub baselines: BTreeMap<String, Baseline>,
    /// The result against the naive centroid, per object and per scene.
    pub vs_naive: BTreeMap<String, BTreeMap<String, VsNaive>>,
    /// Per synthetic set, the frames that failed to render and were left out.
    pub skipped_frames: BTreeMap<String, Vec<u64>>,
    pub rows: Vec<RowRecord>,
    pub settings: Settings,
    pub timing: Timing,
    pub notes: Vec<String>,
    /// The detections on the test frames, scored as bop_toolkit scores them (issue 52).
    pub detection: Option<serde_json::Value>,
    /// The main row from raw frames: its points from the detections' masks (errors over
    /// the detected instances; `no_gt_row` says how many of the GT instances those are).
    pub no_gt: Option<Metrics>,
    pub no_gt_objects: Option<BTreeMap<String, Metrics>>,
    pub no_gt_scenes: Option<BTreeMap<String, Metrics>>,
    pub no_gt_row: Option<NoGtRecord>,
    pub detector: Option<DetectorRecord>,
    /// The main row's poses drawn over real test frames (relative to the output folder).
    pub pictures: Vec<std::path::PathBuf>,
}

impl Report {
    pub fn new(
        settings: &Settings,
        rows: Vec<RowRecord>,
        timing: Timing,
        notes: Vec<String>,
        skipped_frames: BTreeMap<String, Vec<u64>>,
    ) -> Report {
        let main = rows.iter().find(|r| r.name == MAIN_ROW);
        let naive = rows.iter().find(|r| r.name == NAIVE);
        let beside = |m: &BTreeMap<String, Metrics>, n: &BTreeMap<String, Metrics>| {
            m.iter()
                .filter_map(|(k, a)| {
                    let b = n.get(k)?;
                    Some((
                        k.clone(),
                        VsNaive {
                            n: a.n,
                            model_cm: a.mean_centre_error_cm,
                            naive_cm: b.mean_centre_error_cm,
                        },
                    ))
                })
                .collect::<BTreeMap<_, _>>()
        };
        let vs_naive = match (main, naive) {
            (Some(m), Some(n)) => BTreeMap::from([
                ("objects".to_string(), beside(&m.objects, &n.objects)),
                ("scenes".to_string(), beside(&m.scenes, &n.scenes)),
            ]),
            _ => BTreeMap::new(),
        };
        Report {
            all: main.map(|r| r.all.clone()),
            objects: main.map(|r| r.objects.clone()).unwrap_or_default(),
            scenes: main.map(|r| r.scenes.clone()).unwrap_or_default(),
            vs_naive,
            skipped_frames,
            baselines: rows
                .iter()
                .filter(|r| r.name != MAIN_ROW)
                .map(|r| {
                    (
                        r.name.clone(),
                        Baseline {
                            all: r.all.clone(),
                            objects: r.objects.clone(),
                        },
                    )
                })
                .collect(),
            rows,
            settings: settings.clone(),
            timing,
            notes,
            detection: None,
            no_gt: None,
            no_gt_objects: None,
            no_gt_scenes: None,
            no_gt_row: None,
            detector: None,
            pictures: Vec::new(),
        }
    }

    /// The detector's record and the main row from its detections.
    pub fn set_no_gt(&mut self, det: Option<DetectorRecord>, row: Option<NoGtRecord>) {
        self.detection = det.as_ref().map(|d| d.detection.clone());
        self.no_gt = row.as_ref().map(|r| r.all.clone());
        self.no_gt_objects = row.as_ref().map(|r| r.objects.clone());
        self.no_gt_scenes = row.as_ref().map(|r| r.scenes.clone());
        self.no_gt_row = row;
        self.detector = det;
    }

    pub fn write(&self, out: &Path) -> Result<()> {
        atomic_write(
            &out.join("report.json"),
            (serde_json::to_string_pretty(self)? + "\n").as_bytes(),
        )?;
        atomic_write(&out.join("report.md"), self.markdown().as_bytes())?;
        self.plot().write_png(&out.join("plot.png"))?;
        Ok(())
    }

    pub fn markdown(&self) -> String {
        let s = &self.settings;
        // Rotation scores: the rotation models' rows, and TNet's with ICP's rotation.
        let full = self.rows.iter().any(|r| r.all.add_s_acc.is_some());
        let mut o = String::new();
        let _ = writeln!(o, "# Synthetic to real: {} on real frames\n", s.model);
        let _ = writeln!(
            o,
            "Test: {}{} (real depth, real visible masks). Fits: {}{}. {} synthetic frames per set, {} epochs, seed {}{}.\n",
            s.test.display(),
            if s.test_scenes.is_empty() {
                String::new()
            } else {
                format!(", scenes {}", super::list(&s.test_scenes))
            },
            s.fit.display(),
            if s.fit_scenes.is_empty() {
                String::new()
            } else {
                format!(", scenes {}", super::list(&s.fit_scenes))
            },
            s.frames,
            s.epochs,
            s.seed,
            if s.quick { " (--quick)" } else { "" }
        );
        let _ = write!(
            o,
            "| row | trained on | n | mean centre error cm | median cm |"
        );
        if full {
            let _ = write!(
                o,
                " AR | AR_VSD | AR_MSSD | AR_MSPD | ADD-S AUC | ADD(-S) % | 5cm5° % | median te cm | median re ° |"
            );
        }
        let _ = writeln!(o);
        let _ = write!(o, "|---|---|---:|---:|---:|");
        if full {
            let _ = write!(o, "---:|---:|---:|---:|---:|---:|---:|---:|---:|");
        }
        let _ = writeln!(o);
        for r in &self.rows {
            let trained = match &r.trained_on {
                None => "—".to_string(),
                Some(_) => format!("{} inst., {} epochs", r.train_instances, r.epochs),
            };
            let name = if r.name == MAIN_ROW {
                format!("**{}**", r.name)
            } else {
                r.name.clone()
            };
            let _ = write!(
                o,
                "| {name} | {trained} | {} | {:.2} | {:.2} |",
                r.all.n, r.all.mean_centre_error_cm, r.all.median_centre_error_cm
            );
            if full {
                let _ = write!(o, " {} |", rotation_cells(&r.all));
            }
            let _ = writeln!(o);
        }
        let _ = writeln!(o);
        for r in &self.rows {
            let _ = writeln!(o, "- `{}`: {}", r.name, r.what);
        }
        let refined: Vec<&RowRecord> = self
            .rows
            .iter()
            .filter(|r| r.before_refine.is_some())
            .collect();
        if !refined.is_empty() {
            let _ = writeln!(
                o,
                "\nThe trained rows' poses were refined by ICP on the real depth (`--refine icp`: TNet's centre, the fit giving the rotation; Full's whole pose, its rotation deciding between fits the depth cannot tell apart); before and after the refinement, and the share of instances whose fit was kept:\n"
            );
            let _ = writeln!(
                o,
                "| row | mean centre cm before | after | AR before | after | ADD-S AUC before | after | ADD(-S) % before | after | kept % |\n|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|"
            );
            let f = cell;
            for r in refined {
                let b = r.before_refine.as_ref();
                let _ = writeln!(
                    o,
                    "| {} | {} | {} | {} | {} | {} | {} | {} | {} | {:.0} |",
                    r.name,
                    f(b.map(|m| m.mean_centre_error_cm), 1.0, 2),
                    f(Some(r.all.mean_centre_error_cm), 1.0, 2),
                    f(b.and_then(|m| m.ar), 1.0, 3),
                    f(r.all.ar, 1.0, 3),
                    f(b.and_then(|m| m.add_s_auc), 1.0, 1),
                    f(r.all.add_s_auc, 1.0, 1),
                    f(b.and_then(|m| m.add_s_acc), 100.0, 1),
                    f(r.all.add_s_acc, 100.0, 1),
                    100.0 * r.refine_accepted.unwrap_or(0.0)
                );
            }
        }
        // Per object: mean centre error of every row.
        let ids: Vec<String> = {
            let mut v: Vec<String> = self
                .rows
                .iter()
                .flat_map(|r| r.objects.keys().cloned())
                .collect();
            v.sort_by_key(|k| k.parse::<u32>().unwrap_or(u32::MAX));
            v.dedup();
            v
        };
        let mut per_object: Vec<Table> = vec![(
            "Mean centre error (cm) per object",
            |m| Some(m.mean_centre_error_cm),
            2,
        )];
        if full {
            per_object.extend::<[Table; 3]>([
                (
                    "BOP's AR per object (the rows with a rotation; GT masks)",
                    |m| m.ar,
                    3,
                ),
                ("ADD-S AUC (up to 10 cm, %) per object", |m| m.add_s_auc, 1),
                (
                    "Median rotation error (°) per object",
                    |m| m.median_re_deg,
                    1,
                ),
            ]);
        }
        for t in per_object {
            row_table(&mut o, t, "object", &self.rows, &ids, |r| &r.objects);
        }
        // Per test scene, when there are several.
        let scene_ids: Vec<String> = self
            .rows
            .iter()
            .flat_map(|r| r.scenes.keys().cloned())
            .collect::<std::collections::BTreeSet<_>>()
            .into_iter()
            .collect();
        if scene_ids.len() > 1 {
            let mut per_scene: Vec<Table> = vec![(
                "Mean centre error (cm) per test scene",
                |m| Some(m.mean_centre_error_cm),
                2,
            )];
            if full {
                per_scene.push(("BOP's AR per test scene", |m| m.ar, 3));
            }
            for t in per_scene {
                row_table(&mut o, t, "scene", &self.rows, &scene_ids, |r| &r.scenes);
            }
        }
        let skipped: usize = self.skipped_frames.values().map(Vec::len).sum();
        if skipped > 0 {
            let _ = writeln!(
                o,
                "\n{skipped} synthetic frames failed to render and were left out: {}.",
                self.skipped_frames
                    .iter()
                    .filter(|(_, v)| !v.is_empty())
                    .map(|(k, v)| format!("{k} {}", v.len()))
                    .collect::<Vec<_>>()
                    .join(", ")
            );
        }
        let t = &self.timing;
        let join = |m: &BTreeMap<String, f64>| {
            m.iter()
                .map(|(k, v)| format!("{k} {v:.0} s"))
                .collect::<Vec<_>>()
                .join(", ")
        };
        let _ = writeln!(
            o,
            "\nWall time: {:.0} s for all the steps (fits {:.0} s; renders: {}; rows, training and scoring: {}); this invocation {:.0} s.",
            t.steps_total_s,
            t.fit_s,
            join(&t.render_s),
            join(&t.rows_s),
            t.this_run_s
        );
        if let (Some(d), Some(r)) = (&self.detector, &self.no_gt_row) {
            o += &super::detect::markdown(d);
            let main = self.rows.iter().find(|x| x.name == MAIN_ROW);
            let rot_head = if full {
                (
                    " AR | AR_VSD | AR_MSSD | AR_MSPD | ADD-S AUC | ADD(-S) % | 5cm5° % | median te cm | median re ° |",
                    "---:|---:|---:|---:|---:|---:|---:|---:|---:|",
                )
            } else {
                ("", "")
            };
            let _ = write!(
                o,
                "\n{MAIN_ROW} from raw frames (no GT mask anywhere: each instance's points from the detector's mask of its object in its image, best first{}; {} of {} GT instances got one, the others are misses{}):\n\n| masks | n | mean centre error cm | median cm |{}\n|---|---:|---:|---:|{}\n| detected (no GT) | {} | {} | {} |{}\n",
                if s.refine == crate::options::Refine::Icp { ", then ICP as the row" } else { "" },
                r.detected,
                r.n_gt,
                if full { ", counted as wrong in the rotation scores" } else { "" },
                rot_head.0,
                rot_head.1,
                r.all.n,
                cm2(r.all.mean_centre_error_cm),
                cm2(r.all.median_centre_error_cm),
                if full { format!(" {} |", rotation_cells(&r.all)) } else { String::new() }
            );
            if let Some(m) = main {
                let _ = writeln!(
                    o,
                    "| GT visible masks | {} | {:.2} | {:.2} |{}",
                    m.all.n,
                    m.all.mean_centre_error_cm,
                    m.all.median_centre_error_cm,
                    if full {
                        format!(" {} |", rotation_cells(&m.all))
                    } else {
                        String::new()
                    }
                );
            }
            o += if full {
                "\nPer object (mean centre error cm; BOP's AR):\n\n| object | GT | detected | no GT | GT masks | AR no GT | AR GT masks |\n|---|---:|---:|---:|---:|---:|---:|\n"
            } else {
                "\nPer object (mean centre error cm):\n\n| object | GT | detected | no GT | GT masks |\n|---|---:|---:|---:|---:|\n"
            };
            let mut ids: Vec<&String> = r.objects_detected.keys().collect();
            ids.sort_by_key(|k| (k.parse::<u64>().unwrap_or(u64::MAX), (*k).clone()));
            for k in ids {
                let [n, found] = r.objects_detected[k];
                let cm = |m: Option<&Metrics>| {
                    m.map_or("–".to_string(), |m| cm2(m.mean_centre_error_cm))
                };
                let _ = write!(
                    o,
                    "| {k} | {n} | {found} | {} | {} |",
                    cm(r.objects.get(k)),
                    cm(main.and_then(|m| m.objects.get(k)))
                );
                if full {
                    let ar = |m: Option<&Metrics>| {
                        m.and_then(|m| m.ar)
                            .map_or("–".to_string(), |v| format!("{v:.3}"))
                    };
                    let _ = write!(
                        o,
                        " {} | {} |",
                        ar(r.objects.get(k)),
                        ar(main.and_then(|m| m.objects.get(k)))
                    );
                }
                let _ = writeln!(o);
            }
        }
        if !self.pictures.is_empty() {
            let _ = writeln!(
                o,
                "\nThe main row's poses over real test frames (model points in the object's colour, GT in white; `gt_masks_*` with GT masks, `no_gt_*` from raw frames):\n"
            );
            for p in &self.pictures {
                let _ = writeln!(o, "- `{}`", p.display());
            }
        }
        for n in &self.notes {
            let _ = writeln!(o, "\nNote: {n}");
        }
        o
    }

    /// Horizontal bars of the mean centre error per row (the result in blue, synthetic
    /// baselines orange, real-only green, naive grey, naive with ICP light grey), median as
    /// a dark tick.
    pub fn plot(&self) -> Canvas {
        let (w, row_h, top, left) = (760i64, 34i64, 40i64, 250i64);
        let h = top + row_h * self.rows.len() as i64 + 40;
        let mut c = Canvas::new(w as u32, h as u32, [255, 255, 255]);
        c.label(
            10,
            12,
            "MEAN CENTRE ERROR ON THE REAL TEST FRAMES, CM (TICK: MEDIAN)",
            2,
            [20, 20, 20],
        );
        let max = self
            .rows
            .iter()
            .map(|r| r.all.mean_centre_error_cm.max(r.all.median_centre_error_cm))
            .filter(|v| v.is_finite())
            .fold(0.0, f64::max)
            .max(0.1);
        let scale = (w - left - 80) as f64 / max;
        for (k, r) in self.rows.iter().enumerate() {
            let y = top + k as i64 * row_h;
            let color = match r.name.as_str() {
                MAIN_ROW => [31, 119, 180],
                REAL_ONLY => [44, 160, 44],
                NAIVE => [150, 150, 150],
                NAIVE_ICP => [190, 190, 190],
                _ => [255, 127, 14],
            };
            c.label(10, y + 10, &r.name.to_uppercase(), 2, [20, 20, 20]);
            let v = r.all.mean_centre_error_cm;
            if v.is_finite() {
                let len = (v * scale).round() as i64;
                c.fill_rect(left, y + 4, len.max(1), row_h - 10, color);
                c.label(left + len + 6, y + 10, &format!("{v:.2}"), 2, [20, 20, 20]);
            }
            let m = r.all.median_centre_error_cm;
            if m.is_finite() {
                let x = left + (m * scale).round() as i64;
                c.fill_rect(x - 1, y + 1, 3, row_h - 4, [20, 20, 20]);
            }
        }
        c.line(
            (left as f64, top as f64 - 4.0),
            (left as f64, (h - 36) as f64),
            [60, 60, 60],
            2,
        );
        c
    }
}

/// A table cell: `v` times `k` with `d` decimals, "—" where there is no finite value.
fn cell(v: Option<f64>, k: f64, d: usize) -> String {
    v.filter(|v| v.is_finite())
        .map_or("—".into(), |v| format!("{:.d$}", v * k))
}

/// One per-key table of report.md: its title, the number of each row's [`Metrics`] it shows,
/// and that number's decimals.
type Table = (&'static str, fn(&Metrics) -> Option<f64>, usize);

/// The rotation scores of a table row: AR and its parts, ADD-S AUC, ADD(-S) and 5cm5° (%),
/// median translation (cm) and rotation (°) errors; "—" where there is none.
fn rotation_cells(m: &Metrics) -> String {
    let f = cell;
    [
        f(m.ar, 1.0, 3),
        f(m.ar_vsd, 1.0, 3),
        f(m.ar_mssd, 1.0, 3),
        f(m.ar_mspd, 1.0, 3),
        f(m.add_s_auc, 1.0, 1),
        f(m.add_s_acc, 100.0, 1),
        f(m.acc_5cm5deg, 100.0, 1),
        f(m.median_te_cm, 1.0, 2),
        f(m.median_re_deg, 1.0, 1),
    ]
    .join(" | ")
}

/// The titled markdown table `(title, value, digits)` of each row's value per key (an object
/// or a scene id) with `digits` decimals, and the first row's instance count that has the
/// key; "—" where a row lacks it or the value.
fn row_table(
    o: &mut String,
    (title, value, digits): Table,
    what: &str,
    rows: &[RowRecord],
    keys: &[String],
    by: impl Fn(&RowRecord) -> &BTreeMap<String, Metrics>,
) {
    let _ = writeln!(o, "\n{title}:\n");
    let _ = write!(o, "| {what} | n |");
    for r in rows {
        let _ = write!(o, " {} |", r.name);
    }
    let _ = writeln!(o);
    let _ = write!(o, "|---|---:|");
    for _ in rows {
        let _ = write!(o, "---:|");
    }
    let _ = writeln!(o);
    for key in keys {
        let n = rows
            .iter()
            .find_map(|r| by(r).get(key).map(|m| m.n))
            .unwrap_or(0);
        let _ = write!(o, "| {key} | {n} |");
        for r in rows {
            match by(r).get(key).and_then(value).filter(|v| v.is_finite()) {
                Some(v) => {
                    let _ = write!(o, " {v:.digits$} |");
                }
                None => {
                    let _ = write!(o, " — |");
                }
            }
        }
        let _ = writeln!(o);
    }
}

/// A centre error in cm with two digits, "–" where there is none (no instance).
fn cm2(v: f64) -> String {
    if v.is_finite() {
        format!("{v:.2}")
    } else {
        "–".to_string()
    }
}
