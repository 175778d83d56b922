//! `experiment mix`: the study's real/synthetic mixing table in one call. For each composition
//! of a fixed-size training set: `synthgen_curate::mix` (the same held-out real test split for
//! every row), `synthgen_train`, then the errors on the trained frames and on the real test
//! frames. Rows are resumable: a row is done when its `row.json` exists (written atomically,
//! last); an unfinished row is redone from scratch. With `test_scenes` the test split is whole
//! scenes of the real set, and `plus_synth` adds rows "all the real training frames + K× as
//! many synthetic".

mod plot;
mod real;
pub(crate) mod row;
mod sources;
mod table;

use std::path::Path;
use std::time::Instant;

use anyhow::{Context, Result};
use serde::{Deserialize, Serialize};
use synthgen_core::Progress;
use synthgen_curate::mix::{scene_list, SceneRef};
use synthgen_formats::io::atomic_write;
use synthgen_formats::manifest::{write_manifest, Manifest};
use synthgen_formats::output::{check_apart, OutputLock};

use crate::options::{MixOptions, TrainBudget};
use crate::settings::check_settings_file;
use crate::{user_error, Log};

pub use row::RowRecord;

/// The settings file at the output's root; a re-run must match it to resume.
pub const SETTINGS_FILE: &str = "experiment.json";
/// The test split's frames (from the first row's mix), at the output's root.
pub const TEST_SPLIT_FILE: &str = "test_split.json";
pub const TABLE_MD: &str = "table.md";
pub const TABLE_CSV: &str = "table.csv";
pub const PLOT_FILE: &str = "plot.png";
pub const TABLE_OBJECTS_CSV: &str = "table_objects.csv";

/// Everything that decides an experiment's numbers.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Settings {
    pub model: String,
    /// Rows as (real, synthetic) training frame counts, in order.
    pub rows: Vec<(usize, usize)>,
    pub test_count: usize,
    pub epochs: usize,
    pub batch: usize,
    pub lr: f64,
    pub points: usize,
    pub width: usize,
    pub seed: u64,
    pub repeats: usize,
    pub quick: bool,
    pub real: sources::SourceSettings,
    pub synth: sources::SourceSettings,
    /// `--test-scenes`: the test split is every real frame of these scenes (`test_count` of
    /// them); empty: a seeded draw of `test_count` frames.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub test_scenes: Vec<SceneRef>,
    /// `--plus-synth` factors K: rows of `plus_real` real + K × `plus_real` synthetic frames,
    /// after `rows`.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub plus_synth: Vec<usize>,
    /// All the real training frames (the plus rows' real count).
    #[serde(default, skip_serializing_if = "is_zero")]
    pub plus_real: usize,
}

fn is_zero(n: &usize) -> bool {
    *n == 0
}

/// One line of the table: its training frame counts, and K for a `--plus-synth` row.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct RowDef {
    pub real: usize,
    pub synth: usize,
    pub plus: Option<usize>,
}

impl RowDef {
    /// `real 33 + synth 7`; `real 40 + 4× synth 160` for a plus row.
    pub fn label(&self) -> String {
        match self.plus {
            Some(k) => format!("real {} + {k}× synth {}", self.real, self.synth),
            None => format!("real {} + synth {}", self.real, self.synth),
        }
    }
}

impl Settings {
    pub fn real_is_proxy(&self) -> bool {
        self.real.rendered.is_some()
    }

    /// The fixed-total rows, then the plus rows.
    pub fn row_defs(&self) -> Vec<RowDef> {
        let fixed = self.rows.iter().map(|&(real, synth)| RowDef {
            real,
            synth,
            plus: None,
        });
        let plus = self.plus_synth.iter().map(|&k| RowDef {
            real: self.plus_real,
            synth: k * self.plus_real,
            plus: Some(k),
        });
        fixed.chain(plus).collect()
    }
}

/// The study's compositions: `total` split in sixths, all real first.
pub fn default_rows(total: usize) -> Vec<(usize, usize)> {
    (0..=6)
        .map(|k| {
            let synth = (total as f64 * k as f64 / 6.0).round() as usize;
            (total - synth, synth)
        })
        .collect()
}

/// Parses `REAL/SYNTH` counts.
pub fn parse_rows(items: &[String]) -> Result<Vec<(usize, usize)>> {
    items
        .iter()
        .map(|s| {
            let parsed = s
                .split_once('/')
                .and_then(|(r, y)| Some((r.trim().parse().ok()?, y.trim().parse().ok()?)));
            match parsed {
                Some((r, y)) if r + y > 0 => Ok((r, y)),
                _ => Err(user_error(
                    format!("--ratios entry {s:?} is not REAL/SYNTH frame counts"),
                    "e.g. --ratios 1500/0,750/750,0/1500",
                )),
            }
        })
        .collect()
}

/// Runs `experiment mix`; returns the table (Markdown) it also wrote to `table.md`.
pub fn run_mix(args: MixOptions, printer: &Log) -> Result<String> {
    let started = Instant::now();
    let out = args.out.clone();
    // The real set as it is (before any conversion): its scenes and annotated objects.
    let inventory = match &args.real {
        Some(dir) => Some(real::RealInventory::open(&sources::existing(dir, "real")?)?),
        None => None,
    };
    let scene_test = match &inventory {
        Some(inv) if !args.test_scenes.is_empty() => Some(inv.test_frames(&args.test_scenes)?),
        _ => None,
    };
    // Real frames outside the test scenes: all the rows may train on.
    let scene_pool = scene_test
        .as_ref()
        .zip(inventory.as_ref())
        .map(|(t, inv)| inv.len() - t.len());
    let default_total = if args.quick { 42 } else { 1500 };
    let total = args
        .total
        .unwrap_or(scene_pool.map_or(default_total, |p| p.min(default_total)));
    let rows = if args.ratios.is_empty() {
        if total == 0 {
            if scene_pool == Some(0) {
                return Err(user_error(
                    "every real frame is in the --test-scenes: nothing is left to train on",
                    "hold out fewer scenes",
                ));
            }
            return Err(user_error("--total must be positive", "e.g. --total 1500"));
        }
        default_rows(total)
    } else {
        parse_rows(&args.ratios)?
    };
    let max_total = rows.iter().map(|r| r.0 + r.1).max().unwrap_or(total);
    let test_count = match &scene_test {
        Some(t) => t.len(),
        None => args.test_count.unwrap_or(if args.quick {
            8
        } else {
            (max_total / 5).max(1)
        }),
    };
    let budget = args.budget.resolve(args.quick);
    let TrainBudget {
        epochs,
        batch,
        lr,
        points,
        width,
    } = budget;
    if !budget.is_positive() || args.repeats == 0 {
        return Err(user_error(
            "--epochs, --batch, --points, --width and --repeats must be positive",
            "e.g. --epochs 8 --repeats 1",
        ));
    }
    if test_count == 0 {
        return Err(user_error(
            "--test-count must be positive",
            "e.g. --test-count 300",
        ));
    }
    synthgen_jobs::use_threads(args.jobs);
    let inputs: Vec<(&str, &Path)> = [
        ("real dataset", &args.real),
        ("synthetic dataset", &args.synth),
    ]
    .into_iter()
    .filter_map(|(role, p)| Some((role, p.as_deref()?)))
    .collect();
    check_apart(&out, &inputs)?;
    let _lock = OutputLock::acquire(&out)?;
    let max_real = rows.iter().map(|r| r.0).max().unwrap_or(0);
    if let (Some(pool), Some(inv)) = (scene_pool, &inventory) {
        if max_real > pool {
            return Err(user_error(
                format!(
                    "the rows need up to {max_real} real training frames, but only {pool} real \
                     frames lie outside the test scene(s) {} ({} frames, {test_count} of them held \
                     out): {}",
                    scene_list(&args.test_scenes),
                    inv.len(),
                    inv.root.display()
                ),
                format!(
                    "lower --total (or the --ratios) to at most {pool}, or hold out other scenes"
                ),
            ));
        }
    }
    if args.plus_synth.contains(&0) {
        return Err(user_error(
            "--plus-synth factors must be positive",
            "e.g. --plus-synth 1,4,16",
        ));
    }
    // The plus rows train on all the real training frames: those outside the test split
    // (the proxy renders exactly the largest real count of the rows).
    let plus_real = if args.plus_synth.is_empty() {
        0
    } else {
        match (scene_pool, &inventory) {
            (Some(pool), _) => pool,
            (None, Some(inv)) => inv.len().saturating_sub(test_count),
            (None, None) => max_real,
        }
    };
    if plus_real == 0 && !args.plus_synth.is_empty() {
        return Err(user_error(
            "--plus-synth: there are no real training frames to add synthetic frames to",
            "drop --plus-synth, or leave real frames for training",
        ));
    }
    let max_plus = args.plus_synth.iter().max().copied().unwrap_or(0) * plus_real;
    let max_synth = rows.iter().map(|r| r.1).max().unwrap_or(0).max(max_plus);
    let objects = if !args.objects.is_empty() {
        real::RenderObjects {
            paths: args.objects.clone(),
            ids: args.obj_ids.clone(),
            units: None,
        }
    } else if let (None, Some(inv)) = (&args.synth, &inventory) {
        inv.render_objects(scene_test.as_deref(), &args.test_scenes, printer)?
    } else if args.real_proxy || args.synth.is_none() {
        return Err(user_error(
            "no --objects to render the synthetic (or proxy real) set from",
            "pass --objects MESH..., or --real DIR (its annotated models), or both --real DIR and --synth DIR",
        ));
    } else {
        real::RenderObjects::default()
    };
    let plan = sources::plan(
        &args,
        &out,
        max_real + test_count,
        max_synth.max(1),
        &objects,
    )?;
    let settings = Settings {
        model: args.model.name().into(),
        rows: rows.clone(),
        test_count,
        epochs,
        batch,
        lr,
        points,
        width,
        seed: args.seed,
        repeats: args.repeats,
        quick: args.quick,
        real: plan.real.settings.clone(),
        synth: plan.synth.settings.clone(),
        test_scenes: args.test_scenes.clone(),
        plus_synth: args.plus_synth.clone(),
        plus_real,
    };
    check_settings(&out, &settings, args.force)?;
    if let Some(pool) = scene_pool {
        printer.info(format!(
            "test split: every real frame of scene(s) {} ({test_count} frames); the rows' real \
             training frames come from the other {pool}",
            scene_list(&args.test_scenes)
        ));
    }
    if args.objects.is_empty() && args.synth.is_none() && !objects.ids.is_empty() {
        printer.info(format!(
            "the synthetic set shows the real set's annotated objects with models: ids {}",
            objects
                .ids
                .iter()
                .map(u32::to_string)
                .collect::<Vec<_>>()
                .join(", ")
        ));
    }

    if settings.real_is_proxy() {
        printer.warning(
            "the real side is a PROXY: frames rendered by synthgen itself (scenes/real_proxy.toml), \
             not captures; the table says so",
        );
    }
    let real_dir = sources::ensure(&plan.real, &out, &args.command_line, printer)?;
    let synth_dir = sources::ensure(&plan.synth, &out, &args.command_line, printer)?;
    let real = synthgen_formats::layout::open_source(&real_dir)
        .with_context(|| format!("cannot open the real dataset {}", real_dir.display()))?;
    let synth = synthgen_formats::layout::open_source(&synth_dir)
        .with_context(|| format!("cannot open the synthetic dataset {}", synth_dir.display()))?;
    let n_real = real.frames(&[])?.len();
    let n_synth = synth.frames(&[])?.len();
    if n_real < max_real + test_count {
        return Err(user_error(
            format!(
                "the real dataset has {n_real} frames; the rows need up to {max_real} for training \
                 plus {test_count} held out for testing: {}",
                real_dir.display()
            ),
            "lower --total (or give --ratios) or --test-count",
        ));
    }
    if n_synth < max_synth {
        return Err(user_error(
            format!(
                "the synthetic dataset has {n_synth} frames; the rows need up to {max_synth}: {}",
                synth_dir.display()
            ),
            "lower --total, or render more frames",
        ));
    }

    let specs = row::specs(&settings);
    let done: Vec<bool> = specs
        .iter()
        .map(|s| row::read_record(&out, &s.name).is_some())
        .collect();
    let skipped = done.iter().filter(|d| **d).count();
    if skipped > 0 {
        printer.info(format!(
            "resuming: {skipped} of {} rows already finished, kept",
            specs.len()
        ));
    }
    printer.start("experiment", (specs.len() * epochs) as u64);
    printer.advance((skipped * epochs) as u64);
    let ctx = row::RowContext {
        settings: &settings,
        out: &out,
        real: real.as_ref(),
        synth: synth.as_ref(),
        command_line: &args.command_line,
        printer,
    };
    let mut records = Vec::with_capacity(specs.len());
    let mut computed = 0;
    for (spec, done) in specs.iter().zip(done) {
        let record = match (done, row::read_record(&out, &spec.name)) {
            (true, Some(r)) => r,
            _ => {
                let r =
                    row::run(&ctx, spec).with_context(|| format!("row {} failed", spec.name))?;
                computed += 1;
                printer.info(format!(
                    "row {}: train error {:.2} cm, test error {:.2} cm, {:.0} s",
                    spec.name, r.train.centre_error_cm, r.test.centre_error_cm, r.seconds.total
                ));
                r
            }
        };
        records.push(record);
    }
    printer.finish();
    check_same_test_split(&records)?;

    let md = table::markdown(&settings, &records, &real_dir, &synth_dir);
    let csv = table::csv(&settings, &records);
    atomic_write(&out.join(TABLE_MD), md.as_bytes())?;
    atomic_write(&out.join(TABLE_CSV), csv.as_bytes())?;
    atomic_write(
        &out.join(TABLE_OBJECTS_CSV),
        table::objects_csv(&settings, &records).as_bytes(),
    )?;
    plot::write(&out.join(PLOT_FILE), &table::aggregate(&settings, &records))?;
    let mut manifest = Manifest::new(args.command_line.clone(), args.seed);
    manifest.extra = serde_json::json!({ "experiment": settings });
    write_manifest(&out, &manifest)?;

    printer.info(format!(
        "{} rows: {computed} computed, {skipped} skipped (finished earlier); {:.0} s",
        records.len(),
        started.elapsed().as_secs_f64()
    ));
    printer.info(format!(
        "wrote {TABLE_MD}, {TABLE_CSV}, {TABLE_OBJECTS_CSV}, {PLOT_FILE} in {}",
        out.display()
    ));
    if settings.real_is_proxy() {
        printer
            .hint("the real side is a proxy; for captures pass --real DIR (docs/experiments.md)");
    }
    Ok(md)
}

/// Writes the settings, or checks them against those of the experiment already in `out`.
fn check_settings(out: &Path, settings: &Settings, force: bool) -> Result<()> {
    // The datasets the experiment reads (a rendered source is its own, under OUT/sources).
    let source = |s: &sources::SourceSettings| {
        s.rendered
            .is_none()
            .then(|| s.converted_from.clone().unwrap_or_else(|| s.path.clone()))
    };
    let (real, synth) = (source(&settings.real), source(&settings.synth));
    let mut inputs: Vec<(&str, &Path)> = Vec::new();
    if let Some(p) = &real {
        inputs.push(("--real", p));
    }
    if let Some(p) = &synth {
        inputs.push(("--synth", p));
    }
    check_settings_file(
        out,
        SETTINGS_FILE,
        settings,
        &inputs,
        force,
        &["rows", "sources", TEST_SPLIT_FILE],
        false,
    )
}

/// Every row must have been tested on the same real frames.
fn check_same_test_split(records: &[RowRecord]) -> Result<()> {
    if let Some(first) = records.first() {
        for r in records {
            if r.test_split_hash != first.test_split_hash {
                return Err(anyhow::anyhow!(
                    "internal: rows {} and {} have different test splits ({} vs {})",
                    first.name,
                    r.name,
                    first.test_split_hash,
                    r.test_split_hash
                ));
            }
        }
    }
    Ok(())
}

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::expect_used)]
mod tests {
    use super::*;

    #[test]
    fn default_rows_are_the_studys_sixths() {
        assert_eq!(
            default_rows(1500),
            [
                (1500, 0),
                (1250, 250),
                (1000, 500),
                (750, 750),
                (500, 1000),
                (250, 1250),
                (0, 1500)
            ]
        );
        assert!(default_rows(10).iter().all(|(r, s)| r + s == 10));
    }

    #[test]
    fn ratios_parse_as_counts() {
        let rows = parse_rows(&["100/0".into(), " 50 / 50".into()]).unwrap();
        assert_eq!(rows, [(100, 0), (50, 50)]);
        assert!(parse_rows(&["0/0".into()]).is_err());
        assert!(parse_rows(&["0.5".into()]).is_err());
    }
}
