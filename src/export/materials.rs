//! Materials of the baked primitives, in both forms (README, "Using the
//! lightmap in an engine"):
//!
//! - `baked`, the material every primitive draws by default (`--material
//!   preview`): unlit (KHR_materials_unlit) with the baked atlas (albedo·L_lm + emission,
//!   8-bit sRGB) as base colour on texCoord 1. three.js, Babylon.js,
//!   model-viewer and Blender show it exactly as baked, with no plugin.
//!   A cut-out whose alpha comes from its base colour texture shows the
//!   atlas as emission instead, keeping that texture for its alpha
//!   (`push_baked`). A primitive whose own material is unlit keeps it.
//! - `pbr+lightmap`: the input's own material, intact, with the lightmap
//!   referenced through `MOZ_lightmap` {index, texCoord: 1, intensity}: an
//!   8-bit linear PNG of the irradiance E = π·L_lm over its scale s, with
//!   `intensity` = s, as its readers take it (`lightmap.rs`). With
//!   `--material engine` primitives draw this one by default. An unlit input
//!   material shows its own colour whatever the light, so it gains no lightmap
//!   (three.js's addon would light it with one).
//!
//! KHR_materials_variants offers both: variant `baked` maps to the unlit
//! material, `pbr+lightmap` to the lightmapped one. Every extension bake adds
//! is listed in `extensionsUsed` only, never in `extensionsRequired`. A baked
//! file baked again keeps one pair of variants: the material its
//! `pbr+lightmap` variant mapped to is taken as the original.
//!
//! The input's materials keep their indices. One gains `MOZ_lightmap` in
//! place when only baked primitives use it; a copy carries it instead when a
//! primitive that is not baked uses it too, or when the material samples
//! texCoord 1, whose data moved to another set (`primitives.rs`): the copy's
//! texture references (KHR_texture_transform's `texCoord` override included)
//! follow the data.

use std::collections::{BTreeMap, BTreeSet};

use serde_json::{Map, Value, json};

use super::MaterialDefault;
use super::document::Document;
use super::primitives::Rewritten;
use crate::asset::{VARIANT_BAKED, VARIANT_LIGHTMAPPED};

/// The textures the materials use.
#[derive(Clone, Copy, Debug)]
pub struct Textures {
    /// The baked (beauty) atlas, 8-bit sRGB.
    pub baked: usize,
    /// The lightmap as `MOZ_lightmap` reads it: E/s, 8-bit linear.
    pub lightmap: usize,
    /// Its scale s, `MOZ_lightmap`'s `intensity`.
    pub intensity: f64,
}

/// Gives every rewritten primitive its two materials, the one `default`
/// names as its `material`, and the variant mappings between them, and lists
/// the extensions used.
pub fn assign(document: &mut Document, rewritten: &[Rewritten], textures: Textures, default: MaterialDefault) {
    let variants = add_variants(document);
    let others = materials_of_other_primitives(document, rewritten);
    let mut unlit: BTreeMap<(Option<usize>, Option<u32>), usize> = BTreeMap::new();
    let mut lightmapped: BTreeMap<(Option<usize>, Option<u32>), usize> = BTreeMap::new();
    for r in rewritten {
        let primitive = &mut document.json["meshes"][r.mesh]["primitives"][r.primitive];
        // Re-baking a baked file: its `pbr+lightmap` variant holds the original material.
        let material = take_mappings(primitive, variants).or(r.material);
        // A material follows moved UVs only if it samples texCoord 1.
        let original = material.map(|m| document.json["materials"][m].clone());
        let remap = r.moved_uv1_to.filter(|_| original.as_ref().is_some_and(|m| uses_texcoord(m, 1)));
        // An unlit material shows its own colour whatever the light: it stays (a
        // photogrammetry scan's texture holds its lighting already), in both forms.
        let own_light = original.as_ref().is_some_and(is_unlit);
        let lightmap = (!own_light).then_some(textures);
        let pbr = *lightmapped
            .entry((material, remap))
            .or_insert_with(|| lightmapped_material(document, material, remap, &others, lightmap));
        let baked = match own_light {
            true => pbr,
            false => {
                *unlit.entry((material, remap)).or_insert_with(|| push_baked(document, material, remap, textures.baked))
            }
        };
        let primitive = &mut document.json["meshes"][r.mesh]["primitives"][r.primitive];
        primitive["material"] = json!(match default {
            MaterialDefault::Preview => baked,
            MaterialDefault::Engine => pbr,
        });
        let extension = &mut primitive["extensions"]["KHR_materials_variants"];
        if !extension.get("mappings").is_some_and(Value::is_array) {
            extension["mappings"] = json!([]);
        }
        let mappings = extension["mappings"].as_array_mut().unwrap();
        mappings.push(json!({ "material": baked, "variants": [variants.0] }));
        mappings.push(json!({ "material": pbr, "variants": [variants.1] }));
    }
    for name in ["KHR_materials_unlit", "KHR_materials_variants"] {
        document.use_extension(name);
    }
    let materials = document.json.get("materials").and_then(Value::as_array).map(Vec::as_slice).unwrap_or_default();
    if materials.iter().any(|m| m.pointer("/extensions/MOZ_lightmap").is_some()) {
        document.use_extension("MOZ_lightmap");
    }
}

/// The indices of the two variants in the document's list (made if
/// missing): those of a previous bake if the input is one, else appended.
fn add_variants(document: &mut Document) -> (usize, usize) {
    let root = &mut document.json["extensions"]["KHR_materials_variants"];
    if !root.get("variants").is_some_and(Value::is_array) {
        root["variants"] = json!([]);
    }
    let list = root["variants"].as_array_mut().unwrap();
    let mut index_of = |name: &str| match list.iter().position(|v| v["name"] == name) {
        Some(i) => i,
        None => {
            list.push(json!({ "name": name }));
            list.len() - 1
        }
    };
    (index_of(VARIANT_BAKED), index_of(VARIANT_LIGHTMAPPED))
}

/// Removes the primitive's mappings to the two variants (a previous bake's)
/// and returns the material its `pbr+lightmap` variant mapped to, if any.
fn take_mappings(primitive: &mut Value, (baked, lightmapped): (usize, usize)) -> Option<usize> {
    let mappings = primitive.pointer_mut("/extensions/KHR_materials_variants/mappings")?.as_array_mut()?;
    let mut previous = None;
    mappings.retain_mut(|mapping| {
        let material = mapping.get("material").and_then(Value::as_u64).map(|m| m as usize);
        let Some(variants) = mapping.get_mut("variants").and_then(Value::as_array_mut) else { return true };
        if variants.iter().any(|v| v.as_u64() == Some(lightmapped as u64)) {
            previous = material;
        }
        variants.retain(|v| v.as_u64() != Some(baked as u64) && v.as_u64() != Some(lightmapped as u64));
        !variants.is_empty()
    });
    previous
}

/// A material's name without the suffix a previous bake gave it.
fn base_name(material: &Value, fallback: String) -> String {
    let name = material.get("name").and_then(Value::as_str).map_or(fallback, str::to_string);
    name.strip_suffix(&format!(" ({VARIANT_LIGHTMAPPED})")).map(str::to_string).unwrap_or(name)
}

/// Materials used (directly or through a variant) by primitives bake leaves as they are.
fn materials_of_other_primitives(document: &Document, rewritten: &[Rewritten]) -> BTreeSet<usize> {
    let ours: BTreeSet<(usize, usize)> = rewritten.iter().map(|r| (r.mesh, r.primitive)).collect();
    let mut used = BTreeSet::new();
    let meshes = document.json.get("meshes").and_then(Value::as_array).map(Vec::as_slice).unwrap_or_default();
    for (m, mesh) in meshes.iter().enumerate() {
        let primitives = mesh.get("primitives").and_then(Value::as_array).map(Vec::as_slice).unwrap_or_default();
        for (p, primitive) in primitives.iter().enumerate() {
            if ours.contains(&(m, p)) {
                continue;
            }
            used.extend(primitive.get("material").and_then(Value::as_u64).map(|i| i as usize));
            let mappings = primitive.pointer("/extensions/KHR_materials_variants/mappings").and_then(Value::as_array);
            for mapping in mappings.into_iter().flatten() {
                used.extend(mapping.get("material").and_then(Value::as_u64).map(|i| i as usize));
            }
        }
    }
    used
}

/// Whether `material` is unlit (KHR_materials_unlit).
pub fn is_unlit(material: &Value) -> bool {
    material.pointer("/extensions/KHR_materials_unlit").is_some()
}

/// Whether `material` takes its alpha from its base colour texture in a
/// cut-out or a blend (alphaMode MASK or BLEND): its baked form then has to
/// keep that texture, on its own UV set, for the alpha.
pub fn alpha_from_texture(material: &Value) -> bool {
    matches!(material.get("alphaMode").and_then(Value::as_str), Some("MASK" | "BLEND"))
        && material.pointer("/pbrMetallicRoughness/baseColorTexture").is_some()
}

/// The material showing the baked atlas, keeping the original's alpha,
/// alpha mode and sidedness: unlit with the atlas as base colour; or, where
/// the alpha comes from the base colour texture (`alpha_from_texture`),
/// the atlas as emission over a black base colour that keeps that texture
/// for its alpha (an unlit material has one texture, and the atlas cannot
/// hold a cut-out finer than its texels), with KHR_materials_specular's
/// factor 0 so that viewers add no reflection to what was baked.
fn push_baked(document: &mut Document, original: Option<usize>, remap: Option<u32>, texture: usize) -> usize {
    let source = original.map(|m| document.json["materials"][m].clone()).unwrap_or(Value::Null);
    let name = base_name(&source, "default".into());
    let alpha = source.pointer("/pbrMetallicRoughness/baseColorFactor/3").and_then(Value::as_f64).unwrap_or(1.0);
    let atlas = json!({ "index": texture, "texCoord": 1 });
    let mut material = if alpha_from_texture(&source) {
        let mut pbr = json!({
            "baseColorFactor": [0.0, 0.0, 0.0, alpha],
            "baseColorTexture": source["pbrMetallicRoughness"]["baseColorTexture"],
            "metallicFactor": 0.0,
            "roughnessFactor": 1.0,
        });
        if let Some(to) = remap {
            remap_texcoord(&mut pbr, 1, to as u64);
        }
        document.use_extension("KHR_materials_specular");
        json!({
            "pbrMetallicRoughness": pbr,
            "emissiveTexture": atlas,
            "emissiveFactor": [1.0, 1.0, 1.0],
            "extensions": { "KHR_materials_specular": { "specularFactor": 0.0 } },
        })
    } else {
        json!({
            "pbrMetallicRoughness": {
                "baseColorFactor": [1.0, 1.0, 1.0, alpha],
                "baseColorTexture": atlas,
                "metallicFactor": 0.0,
                "roughnessFactor": 1.0,
            },
            "extensions": { "KHR_materials_unlit": {} },
        })
    };
    material["name"] = json!(format!("{name} ({VARIANT_BAKED})"));
    for key in ["doubleSided", "alphaMode", "alphaCutoff"] {
        if let Some(value) = source.get(key) {
            material[key] = value.clone();
        }
    }
    document.push("materials", material)
}

/// The input's material with `MOZ_lightmap` (none where `lightmap` is
/// `None`): in place where that changes nothing for other primitives, else a
/// copy (see the module documentation).
fn lightmapped_material(
    document: &mut Document,
    original: Option<usize>,
    remap: Option<u32>,
    others: &BTreeSet<usize>,
    lightmap: Option<Textures>,
) -> usize {
    let set = |material: &mut Value| match lightmap {
        Some(t) => {
            material["extensions"]["MOZ_lightmap"] =
                json!({ "index": t.lightmap, "texCoord": 1, "intensity": t.intensity })
        }
        // A previous bake's lightmap on a material that takes none now.
        None => {
            if let Some(extensions) = material.get_mut("extensions").and_then(Value::as_object_mut) {
                extensions.remove("MOZ_lightmap");
            }
        }
    };
    match original {
        Some(m) if remap.is_none() && !others.contains(&m) => {
            set(&mut document.json["materials"][m]);
            m
        }
        Some(m) if remap.is_none() && lightmap.is_none() => m,
        Some(m) => {
            let mut copy = document.json["materials"][m].clone();
            if let Some(to) = remap {
                remap_texcoord(&mut copy, 1, to as u64);
            }
            let name = base_name(&copy, format!("material {m}"));
            copy["name"] = json!(format!("{name} ({VARIANT_LIGHTMAPPED})"));
            set(&mut copy);
            document.push("materials", copy)
        }
        // glTF's default material is the empty one.
        None => {
            let mut material = json!({ "name": format!("default ({VARIANT_LIGHTMAPPED})") });
            set(&mut material);
            document.push("materials", material)
        }
    }
}

/// Calls `f` on every textureInfo object in `value`: an object under a key
/// ending in `Texture` that has an `index` (the core material's and those of
/// KHR_materials_* extensions alike).
fn visit_texture_infos(value: &Value, f: &mut impl FnMut(&Map<String, Value>)) {
    match value {
        Value::Object(object) => {
            for (key, child) in object {
                match child {
                    Value::Object(info) if key.ends_with("Texture") && info.contains_key("index") => f(info),
                    _ => visit_texture_infos(child, f),
                }
            }
        }
        Value::Array(items) => items.iter().for_each(|item| visit_texture_infos(item, f)),
        _ => {}
    }
}

fn visit_texture_infos_mut(value: &mut Value, f: &mut impl FnMut(&mut Map<String, Value>)) {
    match value {
        Value::Object(object) => {
            for (key, child) in object.iter_mut() {
                match child {
                    Value::Object(info) if key.ends_with("Texture") && info.contains_key("index") => f(info),
                    _ => visit_texture_infos_mut(child, f),
                }
            }
        }
        Value::Array(items) => items.iter_mut().for_each(|item| visit_texture_infos_mut(item, f)),
        _ => {}
    }
}

/// Whether any texture of `material` reads texture coordinate set `set`,
/// through `texCoord` or KHR_texture_transform's override of it.
pub fn uses_texcoord(material: &Value, set: u64) -> bool {
    let mut found = false;
    visit_texture_infos(material, &mut |info| {
        let own = info.get("texCoord").and_then(Value::as_u64).unwrap_or(0);
        let transformed =
            info.get("extensions").and_then(|e| e.pointer("/KHR_texture_transform/texCoord")).and_then(Value::as_u64);
        found |= own == set || transformed == Some(set);
    });
    found
}

/// Points every texture reference of `material` that reads set `from` at set
/// `to` instead; returns how many references changed.
pub fn remap_texcoord(material: &mut Value, from: u64, to: u64) -> usize {
    let mut changed = 0;
    visit_texture_infos_mut(material, &mut |info| {
        if info.get("texCoord").and_then(Value::as_u64).unwrap_or(0) == from {
            info.insert("texCoord".into(), json!(to));
            changed += 1;
        }
        let transform = info.get_mut("extensions").and_then(|e| e.get_mut("KHR_texture_transform"));
        if let Some(transform) = transform
            && transform.get("texCoord").and_then(Value::as_u64) == Some(from)
        {
            transform["texCoord"] = json!(to);
            changed += 1;
        }
    });
    changed
}

#[cfg(test)]
mod tests {
    use super::*;

    fn material() -> Value {
        json!({
            "name": "crate",
            "pbrMetallicRoughness": {
                "baseColorTexture": { "index": 0, "extensions": { "KHR_texture_transform": { "scale": [2, 2] } } },
                "metallicRoughnessTexture": { "index": 1, "texCoord": 0 },
            },
            "occlusionTexture": { "index": 2, "texCoord": 1, "strength": 0.5 },
            "normalTexture": { "index": 3, "extensions": { "KHR_texture_transform": { "texCoord": 1 } } },
            "extensions": { "KHR_materials_clearcoat": { "clearcoatTexture": { "index": 4, "texCoord": 1 } } },
        })
    }

    #[test]
    fn texcoord_use_is_found_in_core_extensions_and_transforms() {
        assert!(uses_texcoord(&material(), 1));
        assert!(uses_texcoord(&material(), 0));
        assert!(!uses_texcoord(&material(), 2));
        let only_transform = json!({ "normalTexture": { "index": 0, "extensions": {
            "KHR_texture_transform": { "texCoord": 1 } } } });
        assert!(uses_texcoord(&only_transform, 1));
    }

    #[test]
    fn remapping_moves_every_reference_to_the_set_and_nothing_else() {
        let mut m = material();
        assert_eq!(remap_texcoord(&mut m, 1, 3), 3);
        assert_eq!(m["occlusionTexture"]["texCoord"], 3);
        assert_eq!(m["occlusionTexture"]["strength"], 0.5);
        assert_eq!(m["normalTexture"]["extensions"]["KHR_texture_transform"]["texCoord"], 3);
        // The normal map's own texCoord (0, unwritten) is not set 1: untouched.
        assert!(m["normalTexture"].get("texCoord").is_none());
        assert_eq!(m["extensions"]["KHR_materials_clearcoat"]["clearcoatTexture"]["texCoord"], 3);
        assert_eq!(m["pbrMetallicRoughness"]["metallicRoughnessTexture"]["texCoord"], 0);
        assert!(m["pbrMetallicRoughness"]["baseColorTexture"].get("texCoord").is_none());
        assert!(!uses_texcoord(&m, 1));
    }

    #[test]
    fn a_material_shared_with_an_unbaked_primitive_is_copied() {
        let mut document = Document::for_tests(json!({
            "materials": [ { "name": "a" }, { "name": "b" } ],
            "meshes": [ { "primitives": [ { "attributes": {}, "material": 0 }, { "attributes": {}, "material": 1 } ] },
                        { "primitives": [ { "attributes": {}, "material": 1 } ] } ],
        }));
        let rewritten = [
            Rewritten { node: 0, mesh: 0, primitive: 0, material: Some(0), moved_uv1_to: None },
            Rewritten { node: 0, mesh: 0, primitive: 1, material: Some(1), moved_uv1_to: None },
        ];
        assign(&mut document, &rewritten, Textures { baked: 7, lightmap: 8, intensity: 2.5 }, MaterialDefault::Preview);
        let json = &document.json;
        // Material 0: only baked users, lightmapped in place. Material 1 is also drawn by mesh 1: copied.
        assert_eq!(
            json["materials"][0]["extensions"]["MOZ_lightmap"],
            json!({ "index": 8, "texCoord": 1, "intensity": 2.5 })
        );
        assert!(json["materials"][1].get("extensions").is_none());
        let mappings = &json["meshes"][0]["primitives"][1]["extensions"]["KHR_materials_variants"]["mappings"];
        let pbr = mappings[1]["material"].as_u64().unwrap() as usize;
        assert!(pbr > 1 && json["materials"][pbr]["name"] == "b (pbr+lightmap)");
        let baked = json["meshes"][0]["primitives"][1]["material"].as_u64().unwrap() as usize;
        assert_eq!(mappings[0]["material"], baked);
        assert_eq!(json["materials"][baked]["pbrMetallicRoughness"]["baseColorTexture"]["index"], 7);
        assert_eq!(json["meshes"][1]["primitives"][0]["material"], 1);
        assert_eq!(
            json["extensions"]["KHR_materials_variants"]["variants"],
            json!([{"name": "baked"}, {"name": "pbr+lightmap"}])
        );
        assert!(json.get("extensionsRequired").is_none());
    }
}
