//! TEMPORARY STAND-IN until the unwrap branch lands: uvunwrap only.
use anyhow::Result;

pub struct MeshInput<'a> {
    pub positions: &'a [[f32; 3]],
    pub indices: &'a [u32],
}
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub enum Backend {
    Xatlas,
    #[default]
    Uvunwrap,
}
#[derive(Clone, Debug)]
pub struct UnwrapOptions {
    pub backend: Backend,
    pub texels_per_unit: Option<f32>,
    pub max_atlas_size: u32,
    pub padding: u32,
}
impl Default for UnwrapOptions {
    fn default() -> Self {
        UnwrapOptions {
            backend: Backend::default(),
            texels_per_unit: None,
            max_atlas_size: 1024,
            padding: 2,
        }
    }
}
#[derive(Clone, Debug)]
pub struct Atlas {
    pub width: u32,
    pub height: u32,
    pub texels_per_unit: f32,
    pub chart_count: u32,
    pub utilization: f32,
    pub meshes: Vec<UnwrappedMesh>,
    pub notices: Vec<String>,
}
#[derive(Clone, Debug)]
pub struct UnwrappedMesh {
    pub vertices: Vec<AtlasVertex>,
    pub indices: Vec<u32>,
}
#[derive(Clone, Copy, Debug)]
pub struct AtlasVertex {
    pub xref: u32,
    pub uv: [f32; 2],
    pub chart: u32,
}
pub fn run(meshes: &[MeshInput], options: &UnwrapOptions) -> Result<Atlas> {
    let inputs: Vec<uvunwrap::MeshInput> = meshes
        .iter()
        .map(|m| uvunwrap::MeshInput::new(m.positions, m.indices))
        .collect();
    let density = match options.texels_per_unit {
        Some(t) => uvunwrap::Density::Fixed {
            texels_per_unit: t,
            page_size: None,
        },
        None => uvunwrap::Density::Auto {
            page_size: options.max_atlas_size,
        },
    };
    let opts = uvunwrap::Options {
        density,
        padding: options.padding,
        ..Default::default()
    };
    let atlas = uvunwrap::generate(&inputs, &opts)?;
    Ok(Atlas {
        width: atlas.width,
        height: atlas.height,
        texels_per_unit: atlas.texels_per_unit,
        chart_count: atlas.chart_count,
        utilization: atlas.utilization,
        meshes: atlas
            .meshes
            .iter()
            .map(|m| UnwrappedMesh {
                vertices: m
                    .vertices
                    .iter()
                    .map(|v| AtlasVertex {
                        xref: v.xref,
                        uv: v.uv,
                        chart: v.chart.unwrap_or(u32::MAX),
                    })
                    .collect(),
                indices: m.indices.clone(),
            })
            .collect(),
        notices: vec![],
    })
}
impl std::str::FromStr for Backend {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "xatlas" => Ok(Backend::Xatlas),
            "uvunwrap" => Ok(Backend::Uvunwrap),
            _ => Err(format!("unknown unwrapper '{s}'")),
        }
    }
}
impl std::fmt::Display for Backend {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "{}",
            match self {
                Backend::Xatlas => "xatlas",
                Backend::Uvunwrap => "uvunwrap",
            }
        )
    }
}
