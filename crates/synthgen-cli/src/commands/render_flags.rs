//! The flags `synthgen render` and `render --replay` share, as the library's types: the
//! dataset options (`--format`, `--split`, `--chunk-size`, `--rgb-format`, `--depth-scale`,
//! ...) as the pipeline's `SinkOptions`, and the backend flags as its `Backend`.

use anyhow::Result;
use synthgen_pipeline::{Backend as JobBackend, BlenderSettings, Format, ImageFormat, SinkOptions};

use crate::cli::{Backend, FormatArg, RenderArgs, RgbFormat as RgbArg};
use crate::commands::user_error;

pub fn sink_options(args: &RenderArgs) -> SinkOptions {
    SinkOptions {
        format: match args.format {
            FormatArg::Bop => Format::Bop,
            FormatArg::Linemod => Format::Linemod,
            FormatArg::Ycbv => Format::Ycbv,
        },
        split: args.split_name().to_string(),
        chunk_size: args.chunk_size,
        rgb_format: match args.rgb_format {
            RgbArg::Png => ImageFormat::Png,
            RgbArg::Jpg => ImageFormat::Jpg,
        },
        jpg_quality: args.jpg_quality,
        depth_scale: args.depth_scale,
        min_visib_fract: args.min_visib_fract,
    }
}

pub(crate) fn job_backend(args: &RenderArgs) -> JobBackend {
    match args.backend {
        Backend::Cpu => JobBackend::Cpu,
        Backend::Blender => JobBackend::Blender(BlenderSettings {
            venv: args.blender_venv.clone(),
            samples: args.samples,
            denoise: args.denoise,
            threads: args.blender_threads.unwrap_or(0),
        }),
    }
}

pub(crate) fn check_backend(args: &RenderArgs) -> Result<()> {
    match args.backend {
        Backend::Cpu => {
            let blender_only = args.samples != 16
                || args.denoise
                || args.blender_threads.is_some()
                || args.blender_venv.is_some();
            if blender_only {
                return Err(user_error(
                    "--samples, --denoise, --blender-threads and --blender-venv apply only to --backend blender",
                    "add --backend blender, or drop those flags",
                ));
            }
            Ok(())
        }
        Backend::Blender if cfg!(feature = "blender") => Ok(()),
        Backend::Blender => Err(user_error(
            "synthgen was not compiled with the `blender` feature",
            "use --backend cpu (the default), or rebuild with `cargo build -p synthgen-cli --features blender` (docs/blender.md)",
        )),
    }
}
