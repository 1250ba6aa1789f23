//! The integration tests: one binary, a module per concern (shared helpers
//! in `common`), so the crate and wgpu are linked once. The import fuzzer
//! counts allocations with its own global allocator and stays a binary of
//! its own (tests/fuzz_import.rs).

mod bad_input;
mod check;
mod cli;
mod common;
mod determinism;
mod device_loss;
mod draco;
mod engines;
#[allow(clippy::needless_range_loop)]
mod environment;
mod export;
mod extreme;
mod fixtures;
mod furnace;
mod gltfpack;
mod horizon;
mod imports;
mod instancing;
mod ktx2;
mod leaks;
mod lightmap_ktx2;
mod lights;
mod materials;
mod morph;
mod pipeline;
mod probes;
mod punctual;
mod quality;
mod radiosity;
mod reference;
mod report;
mod shaders;
mod shadow;
mod unwrap;
mod validator;
