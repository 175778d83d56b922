//! The two datasets of an experiment: given folders, or sets rendered into `OUT/sources/`
//! through `steps::render` (what `synthgen render` with the recorded arguments runs), cached
//! so that a resumed run does not render again.

use std::path::{Path, PathBuf};

use anyhow::{Context, Result};
use serde::{Deserialize, Serialize};
use synthgen_assets::Units;
use synthgen_core::SceneSpec;
use synthgen_formats::io::atomic_write;
use synthgen_formats::layout::Layout;

use super::real::RenderObjects;
use crate::options::MixOptions;
use crate::settings::absolute;
use crate::user_error;
use crate::Log;
use synthgen_jobs::convert::{convert_dataset, ConvertRequest};
use synthgen_jobs::render::{render, RenderRequest};

/// The stand-in for real captures (`--real-proxy`).
pub const REAL_PROXY_TOML: &str = include_str!("../../../../scenes/real_proxy.toml");
/// The proxy renders with the experiment's seed plus this, so its scenes differ from the
/// synthetic set's even where the specs agree.
pub const PROXY_SEED_OFFSET: u64 = 1_000_003;

/// How a rendered source was made.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RenderSettings {
    /// `synthgen render` arguments, without the program name.
    pub argv: Vec<String>,
    pub frames: u64,
    pub seed: u64,
}

/// Where a dataset of the experiment is, and how it was made when rendered here.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SourceSettings {
    pub path: PathBuf,
    pub rendered: Option<RenderSettings>,
    /// A Linemod-layout folder converted to BOP at `path` (`synthgen convert`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub converted_from: Option<PathBuf>,
}

pub struct SourcePlan {
    pub name: &'static str,
    pub settings: SourceSettings,
    /// What to render (a rendered source): `settings.rendered`'s arguments as data.
    pub call: Option<RenderRequest>,
    /// The scene spec text to write beside a rendered source (the proxy's).
    pub scene_text: Option<&'static str>,
}

pub struct Plan {
    pub real: SourcePlan,
    pub synth: SourcePlan,
}

/// Decides the sources: `real_frames` / `synth_frames` are what a rendered set needs, and
/// `objects` what it shows (the caller has checked there are some where a set is rendered).
pub fn plan(
    args: &MixOptions,
    out: &Path,
    real_frames: usize,
    synth_frames: usize,
    objects: &RenderObjects,
) -> Result<Plan> {
    let sources = absolute(&out.join("sources"));
    let real = match &args.real {
        Some(dir) => {
            let dir = existing(dir, "real")?;
            let layout = synthgen_jobs::convert::layout_of(&dir, None, "--real")?;
            // Linemod and YCB-Video sets are converted to BOP once: the mixes need BOP's
            // mask/ and scene_gt_info, which the conversion computes.
            let settings = if matches!(layout, Layout::Linemod | Layout::Ycbv) {
                SourceSettings {
                    path: sources.join("real_bop"),
                    rendered: None,
                    converted_from: Some(dir),
                }
            } else {
                SourceSettings {
                    path: dir,
                    rendered: None,
                    converted_from: None,
                }
            };
            SourcePlan {
                name: "real_bop",
                settings,
                call: None,
                scene_text: None,
            }
        }
        None => {
            let dir = sources.join("real_proxy");
            let scene = sources.join("real_proxy.toml");
            let spec = SceneSpec::from_toml_str(REAL_PROXY_TOML)
                .context("internal: scenes/real_proxy.toml does not parse")?;
            let seed = args.seed.wrapping_add(PROXY_SEED_OFFSET);
            let (rendered, call) =
                render_settings(args, objects, Some(&scene), &spec, &dir, real_frames, seed)?;
            SourcePlan {
                name: "real_proxy",
                settings: SourceSettings {
                    path: dir.clone(),
                    rendered: Some(rendered),
                    converted_from: None,
                },
                call: Some(call),
                scene_text: Some(REAL_PROXY_TOML),
            }
        }
    };
    let synth = match &args.synth {
        Some(dir) => SourcePlan {
            name: "synth",
            settings: SourceSettings {
                path: existing(dir, "synth")?,
                rendered: None,
                converted_from: None,
            },
            call: None,
            scene_text: None,
        },
        None => {
            let dir = sources.join("synth");
            let scene = match &args.scene {
                Some(p) => Some(existing(p, "scene")?),
                None => None,
            };
            let spec = match &scene {
                Some(p) => SceneSpec::from_toml_file(p)
                    .with_context(|| format!("invalid scene spec {}", p.display()))?,
                None => SceneSpec::default(),
            };
            let (rendered, call) = render_settings(
                args,
                objects,
                scene.as_deref(),
                &spec,
                &dir,
                synth_frames,
                args.seed,
            )?;
            SourcePlan {
                name: "synth",
                settings: SourceSettings {
                    path: dir.clone(),
                    rendered: Some(rendered),
                    converted_from: None,
                },
                call: Some(call),
                scene_text: None,
            }
        }
    };
    Ok(Plan { real, synth })
}

pub(super) fn existing(path: &Path, flag: &str) -> Result<PathBuf> {
    path.canonicalize().map_err(|_| {
        user_error(
            format!("--{flag} not found: {}", path.display()),
            "check the path",
        )
    })
}

/// A rendered source's render: the `synthgen render` arguments it records, and the same
/// as data for the pipeline.
fn render_settings(
    args: &MixOptions,
    objects: &RenderObjects,
    scene: Option<&Path>,
    spec: &SceneSpec,
    dir: &Path,
    frames: usize,
    seed: u64,
) -> Result<(RenderSettings, RenderRequest)> {
    let mut call = RenderRequest {
        scene: scene.map(Path::to_path_buf),
        obj_ids: objects.ids.clone(),
        units: match objects.units {
            Some("mm") => Units::Mm,
            Some("m") => Units::M,
            _ => Units::Auto,
        },
        jobs: args.jobs,
        ..RenderRequest::new(Vec::new(), frames as u64, seed, dir)
    };
    let mut argv: Vec<String> = vec!["render".into()];
    if let Some(s) = scene {
        argv.push("--scene".into());
        argv.push(s.display().to_string());
    }
    argv.push("--objects".into());
    for o in &objects.paths {
        let path = existing(o, "objects")?;
        argv.push(path.display().to_string());
        call.objects.push(path);
    }
    if !objects.ids.is_empty() {
        let ids: Vec<String> = objects.ids.iter().map(u32::to_string).collect();
        argv.push("--obj-ids".into());
        argv.push(ids.join(","));
    }
    if let Some(units) = objects.units {
        argv.extend(["--units".into(), units.into()]);
    }
    argv.extend([
        "--frames".into(),
        frames.to_string(),
        "--seed".into(),
        seed.to_string(),
        "--out".into(),
        dir.display().to_string(),
    ]);
    // With real frames the synthetic ones keep the scene's size: a mixed dataset has one
    // camera.json, and the models that read colour refuse images of another size.
    if args.quick && args.real.is_none() {
        // A quarter of the resolution, with the intrinsics scaled to match.
        let k = spec.camera.intrinsics()?;
        call.overrides.image_size = Some([(k.width / 4).max(8), (k.height / 4).max(8)]);
        call.overrides.camera_k = Some([k.fx / 4.0, k.fy / 4.0, k.cx / 4.0, k.cy / 4.0]);
        argv.extend([
            "--image-size".into(),
            format!("{},{}", (k.width / 4).max(8), (k.height / 4).max(8)),
            "--camera-k".into(),
            format!(
                "{},{},{},{}",
                k.fx / 4.0,
                k.fy / 4.0,
                k.cx / 4.0,
                k.cy / 4.0
            ),
        ]);
    }
    if let Some(j) = args.jobs {
        argv.extend(["--jobs".into(), j.to_string()]);
    }
    Ok((
        RenderSettings {
            argv,
            frames: frames as u64,
            seed,
        },
        call,
    ))
}

/// The dataset folder of `plan`, rendering it first unless a finished render with the same
/// arguments is there (its `OUT/sources/NAME.done` record).
pub fn ensure(
    plan: &SourcePlan,
    out: &Path,
    command_line: &[String],
    printer: &Log,
) -> Result<PathBuf> {
    let dir = plan.settings.path.clone();
    let sources = out.join("sources");
    let marker = sources.join(format!("{}.done", plan.name));
    if let Some(from) = &plan.settings.converted_from {
        return convert(from, &dir, &marker, command_line, printer);
    }
    let Some(r) = &plan.settings.rendered else {
        return Ok(dir);
    };
    std::fs::create_dir_all(&sources)
        .with_context(|| format!("cannot create {}", sources.display()))?;
    let record = serde_json::to_string_pretty(r)? + "\n";
    if std::fs::read_to_string(&marker).is_ok_and(|t| t == record) && dir.is_dir() {
        printer.info(format!(
            "reusing {} ({} frames rendered earlier)",
            dir.display(),
            r.frames
        ));
        return Ok(dir);
    }
    if let Some(text) = plan.scene_text {
        atomic_write(
            &sources.join(format!("{}.toml", plan.name)),
            text.as_bytes(),
        )?;
    }
    if dir.exists() {
        // An interrupted or different render: start it again.
        std::fs::remove_dir_all(&dir)
            .with_context(|| format!("cannot remove {}", dir.display()))?;
    }
    printer.info(format!(
        "rendering the {} set: synthgen {}",
        if plan.name == "synth" {
            "synthetic"
        } else {
            "proxy real"
        },
        r.argv.join(" ")
    ));
    let call = RenderRequest {
        command_line: command_line.to_vec(),
        ..plan
            .call
            .clone()
            .context("internal: a rendered source without its render call")?
    };
    if render(&call, printer)?.too_many_failed {
        return Err(user_error(
            format!("some frames of {} failed to render", dir.display()),
            "see the warnings above",
        ));
    }
    atomic_write(&marker, record.as_bytes())?;
    Ok(dir)
}

/// Converts a Linemod- or YCB-Video-layout real set to BOP once (`OUT/sources/real_bop`),
/// for `mix`.
fn convert(
    from: &Path,
    dir: &Path,
    marker: &Path,
    command_line: &[String],
    printer: &Log,
) -> Result<PathBuf> {
    let record = format!("{}\n", from.display());
    if std::fs::read_to_string(marker).is_ok_and(|t| t == record) && dir.is_dir() {
        printer.info(format!("reusing {} (converted earlier)", dir.display()));
        return Ok(dir.to_path_buf());
    }
    if dir.exists() {
        std::fs::remove_dir_all(dir).with_context(|| format!("cannot remove {}", dir.display()))?;
    }
    let mut request = ConvertRequest::new(from, dir, Layout::Bop);
    printer.info(format!(
        "the real set is not in the BOP layout: {}",
        request.command_line[1..].join(" ")
    ));
    request.command_line = command_line.to_vec();
    convert_dataset(&request, printer).with_context(|| {
        format!(
            "converting {} to BOP failed (`synthgen validate` shows what is wrong)",
            from.display()
        )
    })?;
    if let Some(parent) = marker.parent() {
        std::fs::create_dir_all(parent)
            .with_context(|| format!("cannot create {}", parent.display()))?;
    }
    atomic_write(marker, record.as_bytes())?;
    Ok(dir.to_path_buf())
}
