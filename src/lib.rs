//! `bake`: a lightmap baker for glTF scenes under captured HDR environments.

pub mod environment;
pub mod unwrap;
