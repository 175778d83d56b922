//! Probes the optional dependencies of this crate's tests (synthgen-probe): the tests whose
//! dependency is absent are ignored, with the reason, instead of passing without running.
use synthgen_probe::Check;

fn main() {
    synthgen_probe::emit(&[
        Check::SharedData,
        Check::Python3,
        Check::PythonModules("scipy", &["scipy.io", "numpy"]),
    ]);
}
