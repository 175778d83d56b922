//! The experiment's table (markdown and CSV): one line per composition, mean ± std over the
//! repeats.

use std::path::Path;

use super::row::RowRecord;
use super::Settings;

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
    pub n: usize,
    pub train_cm: Stat,
    pub test_cm: Stat,
    pub test_add_s: Option<Stat>,
    pub test_5cm5deg: Option<Stat>,
    pub seconds: Stat,
}

impl Line {
    pub fn synth_fraction(&self) -> f64 {
        self.synth as f64 / (self.real + self.synth).max(1) as f64
    }
}

pub fn aggregate(settings: &Settings, records: &[RowRecord]) -> Vec<Line> {
    settings
        .rows
        .iter()
        .map(|&(real, synth)| {
            let rs: Vec<&RowRecord> = records
                .iter()
                .filter(|r| r.real == real && r.synth == synth)
                .collect();
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
                n: rs.len(),
                train_cm: stat(&|r| r.train.centre_error_cm),
                test_cm: stat(&|r| r.test.centre_error_cm),
                test_add_s: opt(&|r| r.test.add_s_acc),
                test_5cm5deg: opt(&|r| r.test.acc_5cm5deg),
                seconds: stat(&|r| r.seconds.total),
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

/// The all-real line's test error, the reference of the "vs all-real" column.
fn all_real_test(lines: &[Line]) -> Option<f64> {
    lines.iter().find(|l| l.synth == 0).map(|l| l.test_cm.mean)
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
            s += &format!(" (converted from the Linemod layout of {})", from.display());
        }
        s += "\n\n";
    }
    let hash = records.first().map_or("-", |r| r.test_split_hash.as_str());
    s += &format!(
        "Synthetic frames: {}. Model {}, {} epochs, batch {}, {} points, width {}, lr {}, \
         seed {}, {} repeat(s). Test: the same {} held-out real frames for every row (test split \
         hash {hash}). Errors: mean centre error in cm (train: the frames trained on; test: the \
         real test frames).\n\n",
        synth.display(),
        settings.model,
        settings.epochs,
        settings.batch,
        settings.points,
        settings.width,
        settings.lr,
        settings.seed,
        settings.repeats,
        settings.test_count,
    );
    let reference = all_real_test(&lines);
    s += "| real | synth | synth % | train error cm | test error cm | test vs all-real |";
    if full {
        s += " test ADD(-S) acc % | test 5cm5° acc % |";
    }
    s += " wall s |\n|---:|---:|---:|---:|---:|---:|";
    if full {
        s += "---:|---:|";
    }
    s += "---:|\n";
    for l in &lines {
        let rel = reference.map_or("–".to_string(), |r| {
            format!("{:+.0}%", 100.0 * (l.test_cm.mean / r - 1.0))
        });
        s += &format!(
            "| {} | {} | {:.0} | {} | {} | {rel} |",
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
    s
}

pub fn csv(settings: &Settings, records: &[RowRecord]) -> String {
    let lines = aggregate(settings, records);
    let mut s = String::from(
        "real,synth,synth_fraction,repeats,train_error_cm,train_error_cm_std,test_error_cm,\
         test_error_cm_std,test_add_s_acc,test_add_s_acc_std,test_5cm5deg_acc,\
         test_5cm5deg_acc_std,wall_s,real_is_proxy\n",
    );
    let opt = |o: Option<Stat>| match o {
        Some(v) => (v.mean.to_string(), v.std.to_string()),
        None => (String::new(), String::new()),
    };
    for l in &lines {
        let (a, a_sd) = opt(l.test_add_s);
        let (c, c_sd) = opt(l.test_5cm5deg);
        s += &format!(
            "{},{},{:.4},{},{:.4},{:.4},{:.4},{:.4},{a},{a_sd},{c},{c_sd},{:.1},{}\n",
            l.real,
            l.synth,
            l.synth_fraction(),
            l.n,
            l.train_cm.mean,
            l.train_cm.std,
            l.test_cm.mean,
            l.test_cm.std,
            l.seconds.mean,
            settings.real_is_proxy()
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
