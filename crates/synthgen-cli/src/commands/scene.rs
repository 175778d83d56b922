//! `synthgen scene fit`: a thin skin over `synthgen_fit::scene_fit` (the fit, the TOML
//! text and its read-back check) with the dataset's own models.

use std::fmt::Write as _;
use std::path::Path;

use anyhow::Result;
use synthgen_fit::scene_fit::{self, Observed, SceneFit};

use crate::cli::SceneFitArgs;
use crate::commands::user_error;
use crate::{ExitStatus, Printer};
use synthgen_jobs::fit::fit_scene_to_file;

pub fn run_fit(args: SceneFitArgs, printer: &Printer) -> Result<ExitStatus> {
    if args.out.exists() && !args.force {
        return Err(user_error(
            format!("{} exists", args.out.display()),
            "pass --force to overwrite it, or choose another --out",
        ));
    }
    let fit = fit_scene_to_file(
        &args.data,
        &args.scenes,
        args.sensor.as_deref(),
        &args.out,
        printer,
    )?;
    if args.json {
        printer.data_line(serde_json::to_string_pretty(&fit)?)?;
    } else {
        printer.data(format_fit(&fit, args.sensor.as_deref()))?;
    }
    printer.info(format!("wrote {}", args.out.display()));
    printer.hint(format!(
        "render it: synthgen render --scene {} --frames 1000 --out data/synth",
        args.out.display()
    ));
    if args.sensor.is_none() {
        printer.hint(format!(
            "the scene has no sensor model: fit one with `synthgen sensor fit --data {} --out sensor.toml` and pass it with --sensor",
            args.data.display()
        ));
    }
    Ok(ExitStatus::Success)
}

fn spread(o: &Observed, scale: f64, digits: usize, unit: &str) -> String {
    format!(
        "{:.d$}–{:.d$}{unit} (median {:.d$})",
        o.min * scale,
        o.max * scale,
        o.median * scale,
        d = digits
    )
}

fn format_fit(f: &SceneFit, sensor: Option<&Path>) -> String {
    let s = &f.spec;
    let c = &s.camera_pose;
    let k = f.camera.intrinsics;
    let mut o = String::new();
    let _ = writeln!(
        o,
        "Fitted a scene to {} of {} frames of {}{}; {} skipped.",
        f.frames_used,
        f.frames_total,
        f.data.display(),
        if f.scenes.is_empty() {
            String::new()
        } else {
            format!(
                " (scenes {})",
                f.scenes
                    .iter()
                    .map(u32::to_string)
                    .collect::<Vec<_>>()
                    .join(", ")
            )
        },
        f.frames_skipped.len()
    );
    let _ = writeln!(
        o,
        "camera      {}x{}, fx {} fy {} cx {} cy {} ({} of {} frames)",
        k.width, k.height, k.fx, k.fy, k.cx, k.cy, f.camera.frames, f.frames_used
    );
    let [nx, ny, nz] = f.normal_cam_mean;
    let _ = writeln!(
        o,
        "table       normal in the camera frame ({nx:.2}, {ny:.2}, {nz:.2}) (mean); inliers {:.0} % of the points (median), RMS {:.1} mm",
        f.plane_inlier_share.median * 100.0,
        f.plane_rms_mm.median
    );
    let _ = writeln!(
        o,
        "elevation   {} -> elevation_deg [{}, {}]",
        spread(&f.elevation_deg, 1.0, 1, "°"),
        c.elevation_deg[0],
        c.elevation_deg[1]
    );
    let _ = writeln!(
        o,
        "distance    {} to the look-at point -> distance_m [{}, {}]",
        spread(&f.distance_m, 1.0, 3, " m"),
        c.distance_m[0],
        c.distance_m[1]
    );
    let _ = writeln!(
        o,
        "            {} to the objects' mean centre; camera height above the table {}",
        spread(&f.centre_distance_m, 1.0, 3, " m"),
        spread(&f.camera_height_m, 1.0, 3, " m")
    );
    let _ = writeln!(
        o,
        "roll        {} -> inplane_deg [{}, {}]",
        spread(&f.roll_deg, 1.0, 1, "°"),
        c.inplane_deg[0],
        c.inplane_deg[1]
    );
    let _ = writeln!(
        o,
        "look-at     {} from the objects' mean centre -> look_at_jitter_m {}",
        spread(&f.look_at_offset_m, 1.0, 3, " m"),
        c.look_at_jitter_m
    );
    let _ = writeln!(
        o,
        "azimuth     not identifiable from a few videos -> azimuth_deg [0, 360]"
    );
    let per = s.placement.objects_per_frame.unwrap_or([0, 0]);
    let _ = writeln!(
        o,
        "objects     {}–{} per frame -> objects_per_frame [{}, {}]; centres spread up to {:.3} x {:.3} m -> area_m [{}, {}]",
        f.objects_per_frame.min,
        f.objects_per_frame.max,
        per[0],
        per[1],
        f.extent_m[0],
        f.extent_m[1],
        s.placement.area_m[0],
        s.placement.area_m[1]
    );
    let _ = match &f.occlusion {
        Some(occ) => writeln!(
            o,
            "occlusion   visib_fract mean {:.2}, min {:.2}, {:.0} % of {} instances below 0.5 (from {})",
            occ.visib_fract.mean,
            occ.visib_fract.min,
            occ.share_below_half * 100.0,
            occ.visib_fract.count,
            occ.source
        ),
        None => writeln!(o, "occlusion   not available (no scene_gt_info or visible masks)"),
    };
    let _ = match sensor {
        Some(p) => writeln!(o, "sensor      {}", p.display()),
        None => writeln!(
            o,
            "sensor      none (no --sensor; `synthgen sensor fit` fits one)"
        ),
    };
    let _ = writeln!(
        o,
        "\n{:>4}  {:<22} {:>6}  {:<3} {:>7}  {:>15}  {:>8}  {:>20}  {:>5}",
        "id", "object", "frames", "up", "(of)", "tilt mean/max", "centre", "lowest point", "visib"
    );
    for (ob, spec) in f.objects.iter().zip(&s.objects) {
        let _ = writeln!(
            o,
            "{:>4}  {:<22} {:>6}  {:<3} {:>7}  {:>15}  {:>8}  {:>20}  {:>5}",
            ob.obj_id,
            ob.name,
            ob.frames,
            ob.up.as_str(),
            format!("{}/{}", ob.up_frames, ob.frames),
            format!(
                "{:.1}/{:.1}° → {}",
                ob.tilt_deg.mean, ob.tilt_deg.max, spec.tilt_deg
            ),
            format!("{:.1} cm", ob.centre_height_m.mean * 100.0),
            ob.lowest_point_m.as_ref().map_or("-".into(), |l| format!(
                "{:.1} ({:.1}..{:.1}) cm",
                l.mean * 100.0,
                l.min * 100.0,
                l.max * 100.0
            )),
            ob.visib_fract
                .as_ref()
                .map_or("-".into(), |v| format!("{:.2}", v.mean)),
        );
    }
    let off: Vec<&str> = f
        .objects
        .iter()
        .filter(|o| o.off_table())
        .map(|o| o.name.as_str())
        .collect();
    if !off.is_empty() {
        let _ = writeln!(
            o,
            "\nNot standing on the table (lowest point over {:.0} cm above it: on another object?): {}. \
             The sampler stands every object on the table.",
            scene_fit::OFF_TABLE_M * 100.0,
            off.join(", ")
        );
    }
    o
}
