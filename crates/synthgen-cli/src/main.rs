use std::process::ExitCode;

// mimalloc instead of glibc's malloc: candle's training steps allocate and free many
// megabyte-sized tensors, and glibc hands those pages back to the kernel and faults them in
// again each step; a TNet step is 13 % faster with mimalloc (docs/benchmarks.md).
#[global_allocator]
static GLOBAL: mimalloc::MiMalloc = mimalloc::MiMalloc;

fn main() -> ExitCode {
    synthgen_cli::alloc::keep_freed_memory();
    synthgen_cli::main()
}
