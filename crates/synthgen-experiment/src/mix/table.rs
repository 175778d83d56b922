//! The experiment's table (markdown and CSV): one line per composition, mean ± std over the
//! repeats; and the test error per object (markdown, `table_objects.csv`).

use std::collections::BTreeSet;
use std::path::Path;

use super::row::RowRecord;
use super::{RowDef, Settings};

/// Mean and sample standard deviation (0 for one value); NaN for none.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Stat {
    pub mean: f64,
    pub std: f64,
}

impl Stat {
    pub fn of(values: &[f64]) -> Stat {
        let n = values.len() as f64;
        if values.is_empty() {
            return Stat {
                mean: f64::NAN,
                std: f64::NAN,
            };
        }
        let mean = values.iter().sum::<f64>() / n;
        let std = if values.len() > 1 {
            (values.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (n - 1.0)).sqrt()
        } else {
            0.0
        };
        Stat { mean, std }
    }
}

/// One composition over its repeats.
#[derive(Debug, Clone, PartialEq)]
pub struct Line {
    pub real: usize,
    pub synth: usize,
    /// K of a `--plus-synth` row.
    pub plus: Option<usize>,
    pub n: usize,
    pub train_cm: Stat,
    pub test_cm: Stat,
    pub test_add_s: Option<Stat>,
    pub test_5cm5deg: Option<Stat>,
    pub seconds: Stat,
    pub objects: Vec<ObjectLine>,
}

/// One test object of one composition, over its repeats.
#[derive(Debug, Clone, PartialEq)]
pub struct ObjectLine {
    pub obj_id: u32,
    /// Test instances (the same in every repeat).
    pub n: usize,
    pub test_cm: Stat,
    /// Training instances from real and synthetic frames (the same in every repeat).
    pub n_train_real: usize,
    pub n_train_synth: usize,
}

impl Line {
    pub fn synth_fraction(&self) -> f64 {
        self.synth as f64 / (self.real + self.synth).max(1) as f64
    }

    pub fn def(&self) -> RowDef {
        RowDef {
            real: self.real,
            synth: self.synth,
            plus: self.plus,
        }
    }

    pub fn label(&self) -> String {
        self.def().label()
    }
}

/// The records of one row over its repeats.
fn records_of<'a>(records: &'a [RowRecord], row: &RowDef) -> Vec<&'a RowRecord> {
    records
        .iter()
        .filter(|r| r.real == row.real && r.synth == row.synth && r.plus_synth == row.plus)
        .collect()
}

fn object_lines(rs: &[&RowRecord]) -> Vec<ObjectLine> {
    let ids: BTreeSet<u32> = rs
        .iter()
        .flat_map(|r| r.test_per_object.iter().map(|o| o.obj_id))
        .collect();
    ids.into_iter()
        .map(|id| {
            let of: Vec<_> = rs
                .iter()
                .filter_map(|r| r.test_per_object.iter().find(|o| o.obj_id == id))
                .collect();
            ObjectLine {
                obj_id: id,
                n: of.first().map_or(0, |o| o.n),
                test_cm: Stat::of(&of.iter().map(|o| o.centre_error_cm).collect::<Vec<_>>()),
                n_train_real: of.first().map_or(0, |o| o.n_train_real),
                n_train_synth: of.first().map_or(0, |o| o.n_train_synth),
            }
        })
        .collect()
}

pub fn aggregate(settings: &Settings, records: &[RowRecord]) -> Vec<Line> {
    settings
        .row_defs()
        .iter()
        .map(|row| {
            let (real, synth) = (row.real, row.synth);
            let rs = records_of(records, row);
            let stat = |f: &dyn Fn(&RowRecord) -> f64| {
                Stat::of(&rs.iter().map(|r| f(r)).collect::<Vec<_>>())
            };
            let opt = |f: &dyn Fn(&RowRecord) -> Option<f64>| {
                let v: Option<Vec<f64>> = rs.iter().map(|r| f(r)).collect();
                v.filter(|v| !v.is_empty()).map(|v| Stat::of(&v))
            };
            Line {
                real,
                synth,
                plus: row.plus,
                n: rs.len(),
                train_cm: stat(&|r| r.train.centre_error_cm),
                test_cm: stat(&|r| r.test.centre_error_cm),
                test_add_s: opt(&|r| r.test.add_s_acc),
                test_5cm5deg: opt(&|r| r.test.acc_5cm5deg),
                seconds: stat(&|r| r.seconds.total),
                objects: object_lines(&rs),
            }
        })
        .collect()
}

fn pm(s: Stat, digits: usize, repeats: usize) -> String {
    if repeats > 1 {
        format!("{:.digits$} ± {:.digits$}", s.mean, s.std)
    } else {
        format!("{:.digits$}", s.mean)
    }
}

/// The all-real line (the reference of the "vs all-real" column): the first fixed row
/// without synthetic frames.
pub fn all_real(lines: &[Line]) -> Option<&Line> {
    lines.iter().find(|l| l.synth == 0 && l.plus.is_none())
}

fn all_real_test(lines: &[Line]) -> Option<f64> {
    all_real(lines).map(|l| l.test_cm.mean)
}

pub fn markdown(settings: &Settings, records: &[RowRecord], real: &Path, synth: &Path) -> String {
    let lines = aggregate(settings, records);
    let full = lines.iter().any(|l| l.test_add_s.is_some());
    let mut s = String::from("# Real/synthetic mixing experiment\n\n");
    if settings.real_is_proxy() {
        s += &format!(
            "**The real side is a PROXY**: frames rendered by synthgen itself with \
             scenes/real_proxy.toml (D455 camera and depth noise with holes, RGB noise, other \
             lights and backgrounds, held-out cylinder clutter, another seed), not captured images: {}. The numbers say how \
             the model transfers between two rendered distributions, not to real captures.\n\n",
            real.display()
        );
    } else {
        s += &format!("Real frames: {}", real.display());
        if let Some(from) = &settings.real.converted_from {
            s += &format!(" (converted to BOP from {})", from.display());
        }
        s += "\n\n";
    }
    let hash = records.first().map_or("-", |r| r.test_split_hash.as_str());
    let test = if settings.test_scenes.is_empty() {
        format!("the same {} held-out real frames", settings.test_count)
    } else {
        format!(
            "every real frame of the held-out scene(s) {} ({} frames; no row trains on a real \
             frame of them)",
            synthgen_curate::mix::scene_list(&settings.test_scenes),
            settings.test_count
        )
    };
    s += &format!(
        "Synthetic frames: {}. Model {}, {} epochs, batch {}, {} points, width {}, lr {}, \
         seed {}, {} repeat(s). Test: {test} for every row (test split hash {hash}). Errors: \
         mean centre error in cm (train: the frames trained on; test: the real test frames).\n\n",
        synth.display(),
        settings.model,
        settings.epochs,
        settings.batch,
        settings.points,
        settings.width,
        settings.lr,
        settings.seed,
        settings.repeats,
    );
    if !settings.plus_synth.is_empty() {
        s += &format!(
            "Rows `real {r} + K× synth`: all {r} real training frames plus K × {r} synthetic \
             (--plus-synth).\n\n",
            r = settings.plus_real
        );
    }
    let reference = all_real_test(&lines);
    s += "| row | real | synth | synth % | train error cm | test error cm | test vs all-real |";
    if full {
        s += " test ADD(-S) acc % | test 5cm5° acc % |";
    }
    s += " wall s |\n|---|---:|---:|---:|---:|---:|---:|";
    if full {
        s += "---:|---:|";
    }
    s += "---:|\n";
    for l in &lines {
        let rel = reference.map_or("–".to_string(), |r| {
            format!("{:+.0}%", 100.0 * (l.test_cm.mean / r - 1.0))
        });
        s += &format!(
            "| {} | {} | {} | {:.0} | {} | {} | {rel} |",
            l.label(),
            l.real,
            l.synth,
            100.0 * l.synth_fraction(),
            pm(l.train_cm, 2, l.n),
            pm(l.test_cm, 2, l.n),
        );
        if full {
            let pct = |o: Option<Stat>| {
                o.map_or("–".into(), |v| {
                    pm(
                        Stat {
                            mean: 100.0 * v.mean,
                            std: 100.0 * v.std,
                        },
                        1,
                        l.n,
                    )
                })
            };
            s += &format!(" {} | {} |", pct(l.test_add_s), pct(l.test_5cm5deg));
        }
        s += &format!(" {:.1} |\n", l.seconds.mean);
    }
    s += &objects_markdown(&lines);
    s
}

/// The test error per object: a line per row, a column per test object.
fn objects_markdown(lines: &[Line]) -> String {
    let mut ids: Vec<(u32, usize)> = lines
        .iter()
        .flat_map(|l| l.objects.iter().map(|o| (o.obj_id, o.n)))
        .collect();
    ids.sort_unstable();
    ids.dedup_by_key(|o| o.0);
    if ids.is_empty() {
        return String::new();
    }
    let mut s = String::from(
        "\n## Test error per object\n\nMean centre error, cm, per test object (n: its real test \
         instances). In brackets: the object's training instances from real frames; (0) means \
         the row never saw it in a real frame.\n\n| row |",
    );
    for (id, n) in &ids {
        s += &format!(" obj {id} (n {n}) |");
    }
    s += "\n|---|";
    s += &"---:|".repeat(ids.len());
    s += "\n";
    for l in lines {
        s += &format!("| {} |", l.label());
        for (id, _) in &ids {
            match l.objects.iter().find(|o| o.obj_id == *id) {
                Some(o) => s += &format!(" {} ({}) |", pm(o.test_cm, 2, l.n), o.n_train_real),
                None => s += " – |",
            }
        }
        s += "\n";
    }
    s
}

/// `table_objects.csv`: one line per row and test object.
pub fn objects_csv(settings: &Settings, records: &[RowRecord]) -> String {
    let mut s = String::from(
        "row,real,synth,plus_synth,repeats,obj_id,n_test,test_error_cm,test_error_cm_std,\
         n_train_real,n_train_synth\n",
    );
    for l in aggregate(settings, records) {
        for o in &l.objects {
            s += &format!(
                "{},{},{},{},{},{},{},{:.4},{:.4},{},{}\n",
                l.label(),
                l.real,
                l.synth,
                l.plus.map_or(String::new(), |k| k.to_string()),
                l.n,
                o.obj_id,
                o.n,
                o.test_cm.mean,
                o.test_cm.std,
                o.n_train_real,
                o.n_train_synth
            );
        }
    }
    s
}

pub fn csv(settings: &Settings, records: &[RowRecord]) -> String {
    let lines = aggregate(settings, records);
    let mut s = String::from(
        "real,synth,synth_fraction,repeats,train_error_cm,train_error_cm_std,test_error_cm,\
         test_error_cm_std,test_add_s_acc,test_add_s_acc_std,test_5cm5deg_acc,\
         test_5cm5deg_acc_std,wall_s,real_is_proxy,row,plus_synth\n",
    );
    let opt = |o: Option<Stat>| match o {
        Some(v) => (v.mean.to_string(), v.std.to_string()),
        None => (String::new(), String::new()),
    };
    for l in &lines {
        let (a, a_sd) = opt(l.test_add_s);
        let (c, c_sd) = opt(l.test_5cm5deg);
        s += &format!(
            "{},{},{:.4},{},{:.4},{:.4},{:.4},{:.4},{a},{a_sd},{c},{c_sd},{:.1},{},{},{}\n",
            l.real,
            l.synth,
            l.synth_fraction(),
            l.n,
            l.train_cm.mean,
            l.train_cm.std,
            l.test_cm.mean,
            l.test_cm.std,
            l.seconds.mean,
            settings.real_is_proxy(),
            l.label(),
            l.plus.map_or(String::new(), |k| k.to_string()),
        );
    }
    s
}

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::expect_used)]
mod tests {
    use super::*;

    #[test]
    fn stat_is_mean_and_sample_std() {
        let s = Stat::of(&[1.0, 2.0, 3.0]);
        assert_eq!(s.mean, 2.0);
        assert!((s.std - 1.0).abs() < 1e-12);
        assert_eq!(Stat::of(&[4.0]).std, 0.0);
        assert!(Stat::of(&[]).mean.is_nan());
    }
}
