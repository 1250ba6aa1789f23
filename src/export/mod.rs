//! Export stage: a baked scene in, files out (README, "What it writes" and
//! "Using the lightmap in an engine"):
//!
//! - `NAME.glb`, or with [`Format::Gltf`] `NAME.gltf` + `NAME.bin` + image
//!   files: the input with every field carried through, each baked primitive
//!   given TEXCOORD_1 and two material forms under KHR_materials_variants
//!   (`materials.rs`): the unlit baked atlas any viewer shows, and the
//!   input's PBR material with the lightmap as `MOZ_lightmap` (an 8-bit
//!   linear PNG of the irradiance over its scale, `lightmap.rs`); which one
//!   a primitive draws by default is [`MaterialDefault`].
//! - `NAME.lightmap0.exr`: L_lm per texel in full float HDR.
//! - `NAME.lightmap0.ktx2`: the same L_lm as an engine's float lightmap
//!   (E5B9G9R9, zstd: `ktx2.rs`), which Bevy's `Lightmap` takes as it is;
//!   each node that draws baked primitives names it in `extras.bake`, with
//!   its `uv_rect` and the camera EV100 at which Bevy shows what the preview
//!   shows.
//!
//! The same inputs and options give byte-identical files: nothing here
//! depends on time, hashing order or threads.

pub mod document;
pub mod glb;
pub mod ktx2;
pub mod lightmap;
pub mod materials;
pub mod primitives;
pub mod seams;

use std::collections::BTreeMap;
use std::io::Write;
use std::path::{Path, PathBuf};

use anyhow::{Context, Result};
use serde::{Deserialize, Serialize};
use serde_json::json;

use crate::asset::SourceAsset;
use crate::scene::Scene;
use crate::texelize::TexelSet;
use crate::unwrap::Atlas;
use document::Document;
pub use document::Format;

/// Export options with their defaults.
#[derive(Clone, Debug)]
pub struct ExportOptions {
    /// Exposure in stops applied to the 8-bit preview texture (not to the EXR or the `MOZ_lightmap` texture).
    pub exposure: f32,
    /// Texels of chart padding filled by dilation.
    pub dilation: u32,
    /// `.glb` (default) or `.gltf` + `.bin` + images.
    pub format: Format,
    /// Which material form a baked primitive draws by default (`--material`).
    pub material: MaterialDefault,
}

impl Default for ExportOptions {
    fn default() -> Self {
        ExportOptions { exposure: 0.0, dilation: 4, format: Format::Glb, material: MaterialDefault::Preview }
    }
}

/// The material form a baked primitive draws by default; the other is its
/// KHR_materials_variants variant, which viewers do not select.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum MaterialDefault {
    /// Unlit with the baked atlas: what every viewer shows exactly as baked.
    #[default]
    Preview,
    /// The input's PBR material with `MOZ_lightmap`: what an engine lights,
    /// and what a pipeline that feeds one wants in its files.
    Engine,
}

impl std::fmt::Display for MaterialDefault {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            MaterialDefault::Preview => "preview",
            MaterialDefault::Engine => "engine",
        })
    }
}

impl std::str::FromStr for MaterialDefault {
    type Err = anyhow::Error;

    /// `"preview"` or `"engine"`, case-insensitive.
    fn from_str(s: &str) -> Result<Self> {
        match s.trim().to_ascii_lowercase().as_str() {
            "preview" => Ok(MaterialDefault::Preview),
            "engine" => Ok(MaterialDefault::Engine),
            _ => anyhow::bail!("unknown material form {s:?} (expected \"preview\" or \"engine\")"),
        }
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
    /// UV seams stitched in the lightmap and the baked texture.
    pub stitch: seams::StitchStats,
    /// The `MOZ_lightmap` texture's scale s, its `intensity`: E = π·L_lm = s · RGB/255.
    pub lightmap_intensity: f64,
    pub notices: Vec<String>,
}

/// What export writes out: the scene and the earlier stages' results.
pub struct Input<'a> {
    pub scene: &'a Scene,
    pub atlas: &'a Atlas,
    pub texels: &'a TexelSet,
    /// L_lm per texel of `texels`, linear RGB (the solve's lightmap).
    pub lightmap: &'a [[f32; 3]],
    /// The atlas is the input's own TEXCOORD_1 (`--keep-uv1`), not a new unwrap.
    pub uv1_reused: bool,
    /// `--probes`: the probe volume's files and placement, recorded in each
    /// scene's `extras.bake.probes`.
    pub probes: Option<serde_json::Value>,
}

/// Writes the baked scene into `dir` (which must not hold these files yet)
/// and returns what was written.
pub fn run(baked: &Input, options: &ExportOptions, dir: &Path) -> Result<ExportStats> {
    let (scene, atlas) = (baked.scene, baked.atlas);
    let seam_edges = seams::find(scene, atlas);
    let material_json = |m: Option<usize>| m.and_then(|m| scene.source.json["materials"].get(m));
    let as_emission: Vec<bool> =
        scene.primitives.iter().map(|p| material_json(p.material).is_some_and(materials::alpha_from_texture)).collect();
    let (lightmap, beauty, fixups) =
        lightmap::images(baked.texels, baked.lightmap, &as_emission, options.dilation, &seam_edges);
    lightmap.check_shippable()?;
    let exr_name = format!("{}.lightmap0.exr", scene.name);
    let exr = lightmap.encode_exr()?;
    let ktx2_name = format!("{}.lightmap0.ktx2", scene.name);
    let ktx2_bytes = ktx2::encode(lightmap.width, lightmap.height, &lightmap.pixels)?;
    let beauty_png = beauty.encode_png(options.exposure.exp2())?;
    let scale = lightmap.irradiance_scale();
    let irradiance_png = lightmap.encode_irradiance_png(scale)?;

    let mut document = Document::from_source(&scene.source)?;
    let baked_texture = document.push_png_texture(
        &format!("{} baked lighting", scene.name),
        beauty_png,
        "baked0",
        Some(json!({ "bake": {
            "content": "albedo * L_lm + emission, times 2^exposure, clamped to [0, 1]",
            "encoding": "sRGB",
            "exposure": options.exposure,
        }})),
    );
    let lightmap_texture = document.push_png_texture(
        &format!("{} lightmap", scene.name),
        irradiance_png,
        "lightmap0",
        Some(json!({ "bake": {
            "content": "irradiance E = pi * L_lm over its scale, linear RGB",
            "encoding": "linear",
            "scale": scale,
            "decode": "E = scale * RGB/255 from the raw 8-bit codes (no sRGB decoding); scale is MOZ_lightmap's \
                       intensity; L_lm = E/pi",
            "hdr": exr_name,
        }})),
    );
    let (rewritten, mut notices) = primitives::rewrite(&mut document, scene, atlas, baked.uv1_reused)?;
    notices.extend(record_lightmapped_nodes(&mut document, &rewritten, &ktx2_name, options.exposure));
    if let Some(probes) = &baked.probes {
        notices.extend(record_probes(&mut document, probes));
    }
    materials::assign(
        &mut document,
        &rewritten,
        materials::Textures { baked: baked_texture, lightmap: lightmap_texture, intensity: scale },
        options.material,
    );

    let mut files = Vec::new();
    for (name, bytes) in
        document.into_files(&scene.name, options.format)?.into_iter().chain([(exr_name, exr), (ktx2_name, ktx2_bytes)])
    {
        let path = dir.join(&name);
        write_new(&path, &bytes)?;
        files.push(path);
    }
    Ok(ExportStats {
        files,
        atlas_width: atlas.width,
        atlas_height: atlas.height,
        dilated_texels: fixups.dilated,
        stitch: fixups.stitch,
        lightmap_intensity: scale,
        notices,
    })
}

/// Records in `extras.bake` of each node that draws baked primitives what
/// an engine needs to attach the KTX2 lightmap to them as Bevy's `Lightmap`
/// does (README, "Using the lightmap in an engine"): the file, the UV set
/// and the `uv_rect` over it (the whole atlas: TEXCOORD_1 spans it), which
/// primitives, and the camera EV100 at which Bevy, with no tone mapping and
/// `lightmap_exposure` 1, shows albedo · L_lm as the preview does. Bevy
/// scales the lightmap by 2^-EV100 / 1.2 and the preview by 2^exposure, so
/// EV100 = −exposure − log2 1.2. A node whose extras are not a JSON object
/// keeps them as they are, with a notice.
fn record_lightmapped_nodes(
    document: &mut Document,
    rewritten: &[primitives::Rewritten],
    lightmap: &str,
    exposure: f32,
) -> Vec<String> {
    let mut primitives: BTreeMap<usize, Vec<usize>> = BTreeMap::new();
    for r in rewritten {
        primitives.entry(r.node).or_default().push(r.primitive);
    }
    let ev100 = -f64::from(exposure) - 1.2f64.log2();
    let mut notices = Vec::new();
    for (node, mut drawn) in primitives {
        drawn.sort_unstable();
        drawn.dedup();
        let Some(extras) = extras_object(&mut document.json["nodes"][node]["extras"]) else {
            notices.push(format!(
                "node {node}: its extras are not a JSON object, so they do not name its KTX2 lightmap (extras.bake)"
            ));
            continue;
        };
        extras.insert(
            "bake".into(),
            json!({
                "lightmap": lightmap,
                "texCoord": 1,
                "uv_rect": [0.0, 0.0, 1.0, 1.0],
                "primitives": drawn,
                "content": "L_lm = E/pi per texel, linear RGB (Rec. 709 primaries), E5B9G9R9: Bevy's Lightmap takes \
                            it as it is (no pi, lightmap_exposure 1)",
                "ev100": ev100,
                "ev100_means": "the camera EV100 at which Bevy, with no tone mapping, shows albedo * L_lm as the \
                                unlit preview does",
            }),
        );
    }
    notices
}

/// Records `probes` (the probe volume's files and placement) in
/// `extras.bake.probes` of every scene, where an engine's loader finds them
/// with the file; a scene whose extras are not a JSON object keeps them,
/// with a notice.
fn record_probes(document: &mut Document, probes: &serde_json::Value) -> Vec<String> {
    let count = document.json["scenes"].as_array().map_or(0, Vec::len);
    let mut notices = Vec::new();
    if count == 0 {
        notices.push("the file has no scenes, so none names its light probes (extras.bake)".into());
    }
    for scene in 0..count {
        match extras_object(&mut document.json["scenes"][scene]["extras"]) {
            Some(extras) => {
                extras.insert("bake".into(), json!({ "probes": probes }));
            }
            None => notices.push(format!(
                "scene {scene}: its extras are not a JSON object, so they do not name its light probes (extras.bake)"
            )),
        }
    }
    notices
}

/// `extras` as a JSON object to add to, made one where it was absent;
/// `None` where the input holds something else there (kept as it is).
fn extras_object(extras: &mut serde_json::Value) -> Option<&mut serde_json::Map<String, serde_json::Value>> {
    if extras.is_null() {
        *extras = json!({});
    }
    extras.as_object_mut()
}

/// Writes a file that must not exist yet: two outputs of one run never share a name.
pub fn write_new(path: &Path, bytes: &[u8]) -> Result<()> {
    let write = || -> std::io::Result<()> {
        let mut file = std::fs::OpenOptions::new().write(true).create_new(true).open(path)?;
        file.write_all(bytes)?;
        file.sync_all()
    };
    write().with_context(|| format!("writing {}", path.display()))
}

/// The files an input consists of: the glTF file itself and every external
/// buffer and image it names (data URIs aside). No output may replace them.
pub fn source_files(source: &SourceAsset) -> Vec<PathBuf> {
    let base = source.path.parent().unwrap_or(Path::new("."));
    let buffers = source.document.buffers().filter_map(|b| match b.source() {
        gltf::buffer::Source::Uri(uri) => Some(uri),
        gltf::buffer::Source::Bin => None,
    });
    let images = source.document.images().filter_map(|i| match i.source() {
        gltf::image::Source::Uri { uri, .. } => Some(uri),
        gltf::image::Source::View { .. } => None,
    });
    let external = buffers
        .chain(images)
        .filter(|uri| !uri.starts_with("data:"))
        .filter_map(|uri| crate::asset::percent_decode(uri).ok())
        .map(|relative| base.join(relative));
    std::iter::once(source.path.clone()).chain(external).collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use primitives::Rewritten;

    #[test]
    fn baked_nodes_name_the_ktx2_lightmap_and_keep_their_own_extras() {
        let mut document = Document::for_tests(json!({ "nodes": [
            { "extras": { "layer": "static" } },
            { "extras": { "bake": { "lightmap": "old.lightmap0.ktx2" } } },
            { "extras": "a string" },
            { "name": "not baked" },
        ]}));
        let drawn = |node, primitive| Rewritten { node, mesh: node, primitive, material: None, moved_uv1_to: None };
        let rewritten = [drawn(0, 2), drawn(0, 0), drawn(1, 0), drawn(2, 0)];
        let notices = record_lightmapped_nodes(&mut document, &rewritten, "a.lightmap0.ktx2", 1.0);
        let nodes = &document.json["nodes"];
        assert_eq!(nodes[0]["extras"]["layer"], "static");
        let bake = &nodes[0]["extras"]["bake"];
        assert_eq!((&bake["lightmap"], &bake["primitives"]), (&json!("a.lightmap0.ktx2"), &json!([0, 2])));
        assert_eq!((&bake["texCoord"], &bake["uv_rect"]), (&json!(1), &json!([0.0, 0.0, 1.0, 1.0])));
        // Bevy's 2^-EV100/1.2 equals the preview's 2^exposure.
        let ev100 = bake["ev100"].as_f64().unwrap();
        assert!(((-ev100).exp2() / 1.2 - 2.0).abs() < 1e-12, "{ev100}");
        // A previous bake's record is replaced; extras that are not an object are left, with a notice.
        assert_eq!(nodes[1]["extras"]["bake"]["lightmap"], "a.lightmap0.ktx2");
        assert_eq!(nodes[2]["extras"], "a string");
        assert_eq!(notices.len(), 1);
        assert!(notices[0].starts_with("node 2: its extras are not a JSON object"), "{notices:?}");
        assert_eq!(nodes[3], json!({ "name": "not baked" }));
    }
}
