//! `synthgen view`: serve the datasets to the web browser (synthgen-view), until Ctrl-C.

use std::net::SocketAddr;
use std::time::Instant;

use anyhow::{Context, Result};
use synthgen_view::Viewer;

use crate::cli::ViewArgs;
use crate::{ExitStatus, Printer};

pub fn run(args: ViewArgs, printer: &Printer) -> Result<ExitStatus> {
    let t0 = Instant::now();
    let viewer = Viewer::open(&args.dirs, args.results.as_deref())?;
    for d in &viewer.datasets {
        printer.info(format!(
            "{}: {} frames ({})",
            d.name,
            d.frames.len(),
            d.root.display()
        ));
    }
    printer.info(format!(
        "annotations indexed in {:.2} s; images are read when a page shows them",
        t0.elapsed().as_secs_f64()
    ));
    if !args.host.is_loopback() {
        printer.warning(format!(
            "--host {}: the viewer has no login, and anyone who can reach this machine on that port can read these datasets (read-only); open it by IP address (names other than localhost are refused)",
            args.host
        ));
    }
    let addr = SocketAddr::new(args.host, args.port);
    synthgen_view::serve(viewer, addr, |bound| {
        // The one line on stdout: scripts read the address from it.
        printer.data_line(format!("http://{bound}/"))?;
        printer.info("serving read-only; Ctrl-C stops");
        Ok(())
    })
    .with_context(|| format!("cannot serve on {addr} (is the port taken? try --port 0)"))?;
    Ok(ExitStatus::Success)
}
