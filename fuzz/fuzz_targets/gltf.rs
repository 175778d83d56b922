#![no_main]
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    synthgen_fuzz::quiet_panics();
    synthgen_fuzz::fuzz_gltf(data)
});
