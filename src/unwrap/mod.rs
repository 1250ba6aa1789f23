//! Unwrap stage: world-space triangle meshes in, lightmap UVs (TEXCOORD_1) out.
//!
//! STUB: the interface below is fixed; the implementation is being written.
