//! The one list of WGSL shaders. Only this file knows their paths; each is
//! built into the binary with the shared pieces under `shaders/include/` it
//! uses prepended, in dependency order (WGSL has no includes). Each include
//! file's first line says what it holds and which includes it needs.

/// A shared piece of WGSL under `shaders/include/`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) struct Include {
    /// The file name, for messages.
    file: &'static str,
    pub(super) source: &'static str,
}

macro_rules! include_wgsl {
    ($file:literal) => {
        Include { file: $file, source: include_str!(concat!("../../shaders/include/", $file)) }
    };
}

/// PI, NO_TRIANGLE, the Texel struct, closest_barycentric, the light-space basis.
pub(super) const TEXEL: Include = include_wgsl!("texel.wgsl");
/// The bounce pass's records (Patch, Shooter, BounceParams, ...), sub-cells, luminance.
const BOUNCE: Include = include_wgsl!("bounce.wgsl");
/// Form factors to a parallelogram or a square (Lambert's contour integral).
pub(super) const FORM_FACTOR: Include = include_wgsl!("form_factor.wgsl");
/// A shooter's hemicube: faces, frames and depth-atlas viewports.
const HEMICUBE: Include = include_wgsl!("hemicube.wgsl");
/// Materials and texture sampling (mirrors `gpu::materials`).
const MATERIALS: Include = include_wgsl!("materials.wgsl");
/// Ray casts against the scene (`trace::GpuScene`).
const TRACE: Include = include_wgsl!("trace.wgsl");
/// What can block a point's light (the occluder and direct passes).
const OCCLUDERS: Include = include_wgsl!("occluders.wgsl");

/// Every pass's shader, named `<stage>_<pass>` after its file.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
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

    /// The shared pieces the pass uses, each after those it needs.
    fn includes(self) -> &'static [Include] {
        match self {
            Shader::TexelizeRaster => &[TEXEL],
            Shader::TexelizeAttributes => &[TEXEL, MATERIALS],
            Shader::SolveOccluders | Shader::SolveDirect => &[TEXEL, MATERIALS, TRACE, OCCLUDERS],
            Shader::SolvePatchPower => &[TEXEL, BOUNCE, FORM_FACTOR],
            Shader::SolveSelect => &[TEXEL, BOUNCE, HEMICUBE],
            Shader::SolveHemicube => &[TEXEL, BOUNCE, HEMICUBE, MATERIALS],
            Shader::SolveHemicubeCull => &[TEXEL, BOUNCE, HEMICUBE],
            Shader::SolveShooterCull => &[TEXEL, BOUNCE],
            Shader::SolveShoot => &[TEXEL, BOUNCE, FORM_FACTOR, HEMICUBE],
            Shader::ProbesGather => &[TEXEL, MATERIALS, TRACE],
        }
    }

    /// The complete WGSL source: the pass's includes, then the pass.
    pub fn source(self) -> String {
        let mut source = String::new();
        for include in self.includes() {
            source.push_str(include.source);
            source.push('\n');
        }
        source.push_str(self.body());
        source
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::collections::HashSet;

    /// Every include, in the order a shader lists them.
    const ALL_INCLUDES: &[Include] = &[TEXEL, BOUNCE, FORM_FACTOR, HEMICUBE, MATERIALS, TRACE, OCCLUDERS];

    /// WGSL without its `//` comments.
    fn code(source: &str) -> String {
        source.lines().map(|line| line.split("//").next().unwrap_or("")).collect::<Vec<_>>().join("\n")
    }

    /// Every identifier in `source` outside comments.
    fn identifiers(source: &str) -> HashSet<String> {
        code(source)
            .split(|c: char| !(c.is_ascii_alphanumeric() || c == '_'))
            .filter(|word| !word.is_empty())
            .map(str::to_string)
            .collect()
    }

    /// The names `source` declares at module scope (unindented): fns,
    /// structs, consts, overrides, aliases and vars.
    fn declared(source: &str) -> Vec<String> {
        let mut names = Vec::new();
        for line in code(source).lines() {
            let mut rest = line;
            // Past attributes such as `@group(0) @binding(1)`.
            while let Some(attribute) = rest.strip_prefix('@') {
                rest = &attribute[attribute.find(|c: char| c == '(' || c.is_whitespace()).unwrap_or(attribute.len())..];
                if rest.starts_with('(') {
                    rest = &rest[rest.find(')').map_or(rest.len(), |close| close + 1)..];
                }
                rest = rest.trim_start();
            }
            let Some((keyword, after)) = rest.split_once(|c: char| c.is_whitespace() || c == '<') else {
                continue;
            };
            if !["fn", "struct", "const", "override", "alias", "var"].contains(&keyword) {
                continue;
            }
            // `var<storage, read> name`: past the address space.
            let after = if rest[keyword.len()..].starts_with('<') {
                after.split_once('>').map_or("", |(_, a)| a)
            } else {
                after
            };
            names.push(after.trim_start().chars().take_while(|c| c.is_ascii_alphanumeric() || *c == '_').collect());
        }
        names
    }

    /// The names `source` binds for itself: parameters and members
    /// (`name:`) and locals (`let name`, `var name`), which may shadow a
    /// module-scope name of another include.
    fn bound(source: &str) -> HashSet<String> {
        let code = code(source);
        let mut bound = HashSet::new();
        let mut previous = "";
        for word in code.split(|c: char| !(c.is_ascii_alphanumeric() || c == '_')).filter(|word| !word.is_empty()) {
            let end = word.as_ptr() as usize - code.as_ptr() as usize + word.len();
            if code[end..].trim_start().starts_with(':') || previous == "let" || previous == "var" {
                bound.insert(word.to_string());
            }
            previous = word;
        }
        bound
    }

    /// The other includes whose module-scope names `include` refers to.
    fn needs(include: Include) -> Vec<Include> {
        let bound = bound(include.source);
        let used: HashSet<String> = identifiers(include.source).difference(&bound).cloned().collect();
        ALL_INCLUDES
            .iter()
            .copied()
            .filter(|other| *other != include && declared(other.source).iter().any(|name| used.contains(name)))
            .collect()
    }

    #[test]
    fn a_shader_gets_only_what_it_uses() {
        for &shader in Shader::ALL {
            let includes = shader.includes();
            for (i, include) in includes.iter().enumerate() {
                let rest: Vec<&str> =
                    includes[i + 1..].iter().map(|later| later.source).chain([shader.body()]).collect();
                let used = identifiers(&rest.join("\n"));
                let names = declared(include.source);
                assert!(!names.is_empty(), "{}: declares nothing", include.file);
                assert!(
                    names.iter().any(|name| used.contains(name)),
                    "{}: nothing after {} uses a name it declares",
                    shader.stem(),
                    include.file
                );
            }
        }
    }

    #[test]
    fn includes_come_after_the_includes_they_need() {
        for &shader in Shader::ALL {
            let includes = shader.includes();
            for (i, include) in includes.iter().enumerate() {
                for needed in needs(*include) {
                    assert!(
                        includes[..i].contains(&needed),
                        "{}: {} needs {}, which is not listed before it",
                        shader.stem(),
                        include.file,
                        needed.file
                    );
                }
            }
        }
    }

    #[test]
    fn each_include_says_what_it_needs_on_its_first_line() {
        for &include in ALL_INCLUDES {
            let first = include.source.lines().next().unwrap_or("");
            assert!(first.starts_with("// "), "{}: the first line is not a comment", include.file);
            let mut said: Vec<&str> = first
                .split(|c: char| c.is_whitespace() || c == ',')
                .map(|word| word.trim_end_matches('.'))
                .filter(|word| word.ends_with(".wgsl"))
                .collect();
            said.sort();
            let mut needed: Vec<&str> = needs(include).iter().map(|needed| needed.file).collect();
            needed.sort();
            assert_eq!(said, needed, "{}: its first line names other includes than it needs", include.file);
        }
    }

    #[test]
    fn every_include_file_is_listed_and_used() {
        let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("shaders/include");
        let mut on_disk: Vec<String> =
            std::fs::read_dir(dir).unwrap().map(|e| e.unwrap().file_name().to_string_lossy().into_owned()).collect();
        on_disk.sort();
        let mut listed: Vec<String> = ALL_INCLUDES.iter().map(|include| include.file.to_string()).collect();
        listed.sort();
        assert_eq!(on_disk, listed, "shaders/include/ and ALL_INCLUDES disagree");
        for include in ALL_INCLUDES {
            assert!(
                Shader::ALL.iter().any(|shader| shader.includes().contains(include)),
                "{}: no shader uses it",
                include.file
            );
        }
    }
}
