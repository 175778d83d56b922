#![no_main]
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| synthgen_fuzz::fuzz_ycbv_mat(data));
