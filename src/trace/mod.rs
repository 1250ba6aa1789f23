//! The ray-tracing core: a bounding volume hierarchy over the scene's
//! triangles (`bvh`), CPU ray casts through it (`rays`) against the scene's
//! surfaces with their alpha cut-outs (`surfaces`, `texture`), random
//! directions for those rays (`random`), and the same tree laid out for the
//! GPU passes that cast rays (`gpu_scene`). The solve's CPU fix-ups and the
//! reference path tracer both cast through it; its traversal is tested
//! against brute force over every triangle (`rays`' tests).

pub(crate) mod bvh;
pub(crate) mod gpu_scene;
pub(crate) mod random;
pub(crate) mod rays;
pub(crate) mod surfaces;
pub(crate) mod texture;

pub use gpu_scene::GpuScene;
pub use surfaces::Surfaces;
