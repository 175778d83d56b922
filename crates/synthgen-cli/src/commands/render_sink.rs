//! The dataset options of `synthgen render` (`--format`, `--split`, `--chunk-size`,
//! `--rgb-format`, `--depth-scale`, ...) as the pipeline's `SinkOptions`.

use synthgen_pipeline::{Format, ImageFormat, SinkOptions};

use crate::cli::{FormatArg, RenderArgs, RgbFormat as RgbArg};

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
