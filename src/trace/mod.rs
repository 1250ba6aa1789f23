//! The ray-tracing core: a bounding volume hierarchy over the scene's
//! triangles (`bvh`), shared by the CPU tracer and the GPU passes that cast
//! rays (`gpu_scene` lays it out for them).

pub(crate) mod bvh;
pub(crate) mod gpu_scene;

pub(crate) use gpu_scene::GpuScene;
