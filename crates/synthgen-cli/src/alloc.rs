//! The allocator's one setting: freed memory stays with the process.
//!
//! mimalloc (the binary's global allocator, `main.rs`) hands freed pages back to the kernel a
//! second after they fall empty (v3's default purge delay). A training step frees and
//! allocates the same tens of megabytes of tensors (im2col buffers, activations, gradients),
//! so the pages were faulted in again and zeroed by the kernel, one core at a time: 30 % of
//! the detector's step in `perf` (`clear_page_erms`), 20–40 thousand page faults in an
//! 8-second benchmark against ~600 with purging off (docs/benchmarks.md). With purging off
//! the process keeps its high-water mark (what `maxrss` already reports) and reuses it.
//! `MIMALLOC_PURGE_DELAY` in the environment still decides when it is set.
//!
//! The project's one `unsafe`: two calls into mimalloc's C option API (no Rust binding of
//! them without a new dependency), each with plain integers.
#![allow(unsafe_code)]

use std::os::raw::{c_int, c_long};

// Links mimalloc where the binary's allocator does not (the library's tests).
use mimalloc as _;

/// `mi_option_purge_delay` in mimalloc v3's `mi_option_t` (the version libmimalloc-sys builds
/// by default; the same index in v2); [`tests::the_option_is_the_purge_delay`] checks the index by its default.
const MI_OPTION_PURGE_DELAY: c_int = 15;

extern "C" {
    #[cfg(test)]
    fn mi_option_get(option: c_int) -> c_long;
    fn mi_option_set(option: c_int, value: c_long);
}

/// Turns mimalloc's purging off unless the user set `MIMALLOC_PURGE_DELAY`.
pub fn keep_freed_memory() {
    if std::env::var_os("MIMALLOC_PURGE_DELAY").is_none() {
        // SAFETY: mimalloc's option calls take a plain integer; setting an option at run
        // time is supported (the allocator reads it on each purge decision).
        unsafe { mi_option_set(MI_OPTION_PURGE_DELAY, -1) };
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The purge delay mimalloc uses now, in milliseconds (-1: never).
    fn purge_delay_ms() -> i64 {
        // SAFETY: reading an option has no precondition.
        unsafe { mi_option_get(MI_OPTION_PURGE_DELAY) as i64 }
    }

    #[test]
    #[allow(clippy::print_stderr)]
    fn the_option_is_the_purge_delay() {
        if std::env::var_os("MIMALLOC_PURGE_DELAY").is_some() {
            eprintln!("skipped: MIMALLOC_PURGE_DELAY is set in this environment");
            return;
        }
        // mimalloc v3's default purge delay is 1000 ms (v2's 10 ms); no neighbouring option
        // has either default, so a shifted index fails here.
        assert!(
            matches!(purge_delay_ms(), 1000 | 10),
            "{}",
            purge_delay_ms()
        );
        keep_freed_memory();
        assert_eq!(purge_delay_ms(), -1);
    }
}
