//! The one list of WGSL shaders. Only this file knows their paths; each is
//! built into the binary and gets `shaders/common.wgsl` prepended (WGSL has
//! no includes).

/// Shared WGSL: constants, the light-space basis, packing helpers.
pub const COMMON: &str = include_str!("../../shaders/common.wgsl");
/// Ray casts against the scene (`trace::GpuScene`).
const TRACE: &str = include_str!("../../shaders/include/trace.wgsl");
/// What can block a point's light (the occluder and direct passes).
const OCCLUDERS: &str = include_str!("../../shaders/include/occluders.wgsl");

/// Every pass's shader, named `<stage>_<pass>` after its file.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Shader {
    /// Rasterizes triangles in lightmap-UV space: nearest triangle per texel and exact covered area.
    TexelizeRaster,
    /// Turns (triangle, barycentrics) per texel into world position, normals, albedo, emission.
    TexelizeAttributes,
    /// What can block each point's light: polygons and cones above its face.
    SolveOccluders,
    /// Direct environment light: every point gathers the lights of one batch.
    SolveDirect,
    /// Per-patch sums of unshot power.
    SolvePatchPower,
    /// Picks the batch's shooter patches and totals the unshot power.
    SolveSelect,
    /// Hemicube depth maps from each shooter.
    SolveHemicube,
    /// Lists the casters each hemicube face of a batch can see.
    SolveHemicubeCull,
    /// Which shooters of a batch each group of receiver texels can take light from.
    SolveShooterCull,
    /// Every texel gathers the batch's shots.
    SolveShoot,
    /// Each light probe's ambient cube from the lights and the solved surfaces.
    ProbesGather,
}

impl Shader {
    pub const ALL: &'static [Shader] = &[
        Shader::TexelizeRaster,
        Shader::TexelizeAttributes,
        Shader::SolveOccluders,
        Shader::SolveDirect,
        Shader::SolvePatchPower,
        Shader::SolveSelect,
        Shader::SolveHemicube,
        Shader::SolveHemicubeCull,
        Shader::SolveShooterCull,
        Shader::SolveShoot,
        Shader::ProbesGather,
    ];

    /// The file stem, also used as the pipeline label.
    pub fn stem(self) -> &'static str {
        match self {
            Shader::TexelizeRaster => "texelize_raster",
            Shader::TexelizeAttributes => "texelize_attributes",
            Shader::SolveOccluders => "solve_occluders",
            Shader::SolveDirect => "solve_direct",
            Shader::SolvePatchPower => "solve_patch_power",
            Shader::SolveSelect => "solve_select",
            Shader::SolveHemicube => "solve_hemicube",
            Shader::SolveHemicubeCull => "solve_hemicube_cull",
            Shader::SolveShooterCull => "solve_shooter_cull",
            Shader::SolveShoot => "solve_shoot",
            Shader::ProbesGather => "probes_gather",
        }
    }

    fn body(self) -> &'static str {
        match self {
            Shader::TexelizeRaster => include_str!("../../shaders/texelize_raster.wgsl"),
            Shader::TexelizeAttributes => include_str!("../../shaders/texelize_attributes.wgsl"),
            Shader::SolveOccluders => include_str!("../../shaders/solve_occluders.wgsl"),
            Shader::SolveDirect => include_str!("../../shaders/solve_direct.wgsl"),
            Shader::SolvePatchPower => include_str!("../../shaders/solve_patch_power.wgsl"),
            Shader::SolveSelect => include_str!("../../shaders/solve_select.wgsl"),
            Shader::SolveHemicube => include_str!("../../shaders/solve_hemicube.wgsl"),
            Shader::SolveHemicubeCull => include_str!("../../shaders/solve_hemicube_cull.wgsl"),
            Shader::SolveShooterCull => include_str!("../../shaders/solve_shooter_cull.wgsl"),
            Shader::SolveShoot => include_str!("../../shaders/solve_shoot.wgsl"),
            Shader::ProbesGather => include_str!("../../shaders/probes_gather.wgsl"),
        }
    }

    /// The shared pieces the pass uses, after common.wgsl.
    fn includes(self) -> &'static [&'static str] {
        match self {
            Shader::SolveOccluders | Shader::SolveDirect => &[TRACE, OCCLUDERS],
            Shader::ProbesGather => &[TRACE],
            _ => &[],
        }
    }

    /// The complete WGSL source: common code, the pass's includes, then the pass.
    pub fn source(self) -> String {
        let mut source = String::from(COMMON);
        for include in self.includes() {
            source.push('\n');
            source.push_str(include);
        }
        source.push('\n');
        source.push_str(self.body());
        source
    }
}
