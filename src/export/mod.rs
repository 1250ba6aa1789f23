//! Export stage: Scene + Atlas + TexelSet + Solution in, files out:
//! `<name>.glb` (the input with TEXCOORD_1 and the baked lighting shown by
//! any viewer) and `<name>.lightmap0.exr` (L_lm per texel in full HDR).
//!
//! What a viewer shows: every baked primitive's default material is
//! KHR_materials_unlit with the baked atlas (albedo·L_lm + emission, scaled
//! by 2^exposure, clamped, 8-bit sRGB) as base colour on texCoord 1 — the
//! form three.js, Babylon.js and model-viewer all display as baked.

pub mod document;
pub mod glb;
pub mod lightmap;

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use anyhow::{Context, Result};
use serde::{Deserialize, Serialize};
use serde_json::{Value, json};

use crate::scene::Scene;
use crate::solve::Solution;
use crate::texelize::TexelSet;
use crate::unwrap::Atlas;
use document::Document;

/// Export options with their defaults.
#[derive(Clone, Debug)]
pub struct ExportOptions {
    /// Exposure in stops applied to the 8-bit preview texture (not to the EXR).
    pub exposure: f32,
    /// Texels of chart padding filled by dilation.
    pub dilation: u32,
}

impl Default for ExportOptions {
    fn default() -> Self {
        ExportOptions { exposure: 0.0, dilation: 4 }
    }
}

/// What export wrote, for the report.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct ExportStats {
    pub files: Vec<PathBuf>,
    pub atlas_width: u32,
    pub atlas_height: u32,
    /// Padding texels filled by dilation.
    pub dilated_texels: usize,
    pub notices: Vec<String>,
}

/// Writes the baked scene into `dir` and returns what was written.
pub fn run(
    scene: &Scene,
    atlas: &Atlas,
    texels: &TexelSet,
    solution: &Solution,
    options: &ExportOptions,
    dir: &Path,
) -> Result<ExportStats> {
    let (lightmap, beauty, dilated_texels) = lightmap::images(texels, solution, options.dilation);
    let exposure = options.exposure.exp2();
    let png = beauty.encode_png(exposure)?;
    let exr = lightmap.encode_exr()?;

    let mut document = Document::from_source(&scene.source)?;
    let texture = document.push_png_texture(&format!("{} baked lighting", scene.name), &png);
    document.use_extension("KHR_materials_unlit");
    let mut baked_materials: HashMap<Option<usize>, usize> = HashMap::new();
    let mut material_for = |doc: &mut Document, original: Option<usize>| -> usize {
        *baked_materials.entry(original).or_insert_with(|| {
            let source = original.map(|m| doc.json["materials"][m].clone()).unwrap_or(Value::Null);
            let name = source.get("name").and_then(Value::as_str).unwrap_or("default");
            let alpha =
                source.pointer("/pbrMetallicRoughness/baseColorFactor/3").and_then(Value::as_f64).unwrap_or(1.0);
            let mut material = json!({
                "name": format!("{name} (baked)"),
                "pbrMetallicRoughness": {
                    "baseColorFactor": [1.0, 1.0, 1.0, alpha],
                    "baseColorTexture": { "index": texture, "texCoord": 1 },
                    "metallicFactor": 0.0,
                    "roughnessFactor": 1.0,
                },
                "extensions": { "KHR_materials_unlit": {} },
            });
            for key in ["doubleSided", "alphaMode", "alphaCutoff"] {
                if let Some(value) = source.get(key) {
                    material[key] = value.clone();
                }
            }
            let materials = doc.json.get_mut("materials").and_then(Value::as_array_mut);
            match materials {
                Some(list) => {
                    list.push(material);
                    list.len() - 1
                }
                None => {
                    doc.json["materials"] = json!([material]);
                    0
                }
            }
        })
    };
    let notices = document::rewrite_primitives(&mut document, scene, atlas, &mut material_for)?;
    let glb = document.to_glb()?;

    let glb_path = dir.join(format!("{}.glb", scene.name));
    let exr_path = dir.join(format!("{}.lightmap0.exr", scene.name));
    std::fs::write(&glb_path, glb).with_context(|| format!("writing {}", glb_path.display()))?;
    std::fs::write(&exr_path, exr).with_context(|| format!("writing {}", exr_path.display()))?;
    Ok(ExportStats {
        files: vec![glb_path, exr_path],
        atlas_width: atlas.width,
        atlas_height: atlas.height,
        dilated_texels,
        notices,
    })
}
