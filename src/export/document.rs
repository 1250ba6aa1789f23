//! The output document under construction: the input's glTF JSON with every
//! field carried through, one binary buffer holding all input buffers and the
//! new data, and the images that are not in that buffer yet. It packages as a
//! `.glb` (images embedded) or as `.gltf` + `.bin` + image files.

use anyhow::{Context, Result, anyhow};
use serde_json::{Value, json};

use crate::asset::SourceAsset;

/// How the output is packaged (`--format`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Format {
    /// `NAME.glb`: one binary file, every image embedded.
    #[default]
    Glb,
    /// `NAME.gltf` (JSON) + `NAME.bin` + one file per image that is not in the input's buffers.
    Gltf,
}

impl std::fmt::Display for Format {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Format::Glb => "glb",
            Format::Gltf => "gltf",
        })
    }
}

impl std::str::FromStr for Format {
    type Err = anyhow::Error;

    /// `"glb"` or `"gltf"`, case-insensitive.
    fn from_str(s: &str) -> Result<Self> {
        match s.trim().to_ascii_lowercase().as_str() {
            "glb" => Ok(Format::Glb),
            "gltf" => Ok(Format::Gltf),
            _ => Err(anyhow!("unknown output format {s:?} (expected \"glb\" or \"gltf\")")),
        }
    }
}

/// An image whose bytes are placed when the document is packaged.
struct PendingImage {
    /// Index in `images`.
    index: usize,
    bytes: Vec<u8>,
    mime: String,
    /// File name part after the output stem, without extension (`.gltf` form only).
    suffix: String,
}

/// The output document under construction, with its binary buffer.
pub struct Document {
    pub json: Value,
    pub bin: Vec<u8>,
    images: Vec<PendingImage>,
}

impl Document {
    /// The input's document with all its buffers merged into one buffer.
    /// Images the input keeps in buffer views stay there; images it keeps in
    /// files or data URIs are read and become pending images (`imageN`).
    pub fn from_source(source: &SourceAsset) -> Result<Document> {
        let mut json = source.json.clone();
        let mut bin = Vec::new();
        let mut starts = Vec::new();
        for (i, data) in source.buffers.iter().enumerate() {
            align(&mut bin, 8);
            starts.push(bin.len());
            let declared = source.document.buffers().nth(i).map_or(data.len(), |b| b.length());
            bin.extend_from_slice(&data[..declared.min(data.len())]);
        }
        if let Some(views) = json.get_mut("bufferViews").and_then(Value::as_array_mut) {
            for view in views {
                let buffer = view["buffer"].as_u64().unwrap_or(0) as usize;
                let offset = view.get("byteOffset").and_then(Value::as_u64).unwrap_or(0) as usize;
                view["buffer"] = json!(0);
                view["byteOffset"] = json!(starts.get(buffer).copied().unwrap_or(0) + offset);
            }
        }
        // A lone input buffer's name and extras describe the merged one as well.
        if let Some([only]) = json.get("buffers").and_then(Value::as_array).map(Vec::as_slice) {
            let mut kept = only.clone();
            if let Some(object) = kept.as_object_mut() {
                object.remove("uri");
                object.remove("byteLength");
            }
            json["buffers"] = json!([kept]);
        } else {
            json["buffers"] = json!([{}]);
        }
        let mut document = Document { json, bin, images: Vec::new() };
        for i in 0..source.document.images().len() {
            if document.json["images"][i].get("uri").is_none() {
                continue;
            }
            let (bytes, mime) = source.image_bytes(i)?;
            let mime = mime.or_else(|| sniff_image_mime(&bytes).map(str::to_string)).ok_or_else(|| {
                anyhow!("image {i}: unknown format (neither PNG, JPEG, WebP nor KTX2), cannot carry it")
            })?;
            if let Some(image) = document.json["images"][i].as_object_mut() {
                image.remove("uri");
            }
            document.images.push(PendingImage { index: i, bytes, mime, suffix: format!("image{i}") });
        }
        Ok(document)
    }

    /// A document around `json` with an empty buffer (unit tests).
    #[cfg(test)]
    pub fn for_tests(json: Value) -> Document {
        Document { json, bin: Vec::new(), images: Vec::new() }
    }

    fn array(&mut self, key: &str) -> &mut Vec<Value> {
        if !self.json.get(key).is_some_and(Value::is_array) {
            self.json[key] = json!([]);
        }
        self.json[key].as_array_mut().unwrap()
    }

    /// Appends `value` to the top-level array `key` (created if missing); returns its index.
    pub fn push(&mut self, key: &str, value: Value) -> usize {
        let array = self.array(key);
        array.push(value);
        array.len() - 1
    }

    /// Appends `bytes` as a new buffer view (4-byte aligned) and returns its index.
    pub fn push_view(&mut self, bytes: &[u8], target: Option<u32>) -> usize {
        align(&mut self.bin, 4);
        let mut view = json!({ "buffer": 0, "byteOffset": self.bin.len(), "byteLength": bytes.len() });
        if let Some(target) = target {
            view["target"] = json!(target);
        }
        self.bin.extend_from_slice(bytes);
        self.push("bufferViews", view)
    }

    /// Adds a PNG image with a linear, clamped, unmipmapped sampler and
    /// returns the texture's index. `suffix` names its file in the `.gltf`
    /// form (`NAME.<suffix>.png`); `extras` go on the texture.
    pub fn push_png_texture(&mut self, name: &str, png: Vec<u8>, suffix: &str, extras: Option<Value>) -> usize {
        const LINEAR: u32 = 9729;
        const CLAMP_TO_EDGE: u32 = 33071;
        let image = self.push("images", json!({ "name": name }));
        self.images.push(PendingImage { index: image, bytes: png, mime: "image/png".into(), suffix: suffix.into() });
        // No mipmaps: minification between charts would bleed across them.
        let sampler = self.push(
            "samplers",
            json!({ "magFilter": LINEAR, "minFilter": LINEAR, "wrapS": CLAMP_TO_EDGE, "wrapT": CLAMP_TO_EDGE }),
        );
        let mut texture = json!({ "name": name, "source": image, "sampler": sampler });
        if let Some(extras) = extras {
            texture["extras"] = extras;
        }
        self.push("textures", texture)
    }

    /// Lists `name` in `extensionsUsed` (never in `extensionsRequired`).
    pub fn use_extension(&mut self, name: &str) {
        let used = self.array("extensionsUsed");
        if !used.iter().any(|v| v == name) {
            used.push(json!(name));
        }
    }

    /// The finished output as (file name, bytes): `<stem>.glb`, or
    /// `<stem>.gltf`, `<stem>.bin` and the image files.
    pub fn into_files(mut self, stem: &str, format: Format) -> Result<Vec<(String, Vec<u8>)>> {
        let mut files = Vec::new();
        let images = std::mem::take(&mut self.images);
        for image in images {
            let entry = &mut self.json["images"][image.index];
            match format {
                Format::Glb => {
                    let view = self.push_view(&image.bytes, None);
                    let entry = &mut self.json["images"][image.index];
                    entry["bufferView"] = json!(view);
                    entry["mimeType"] = json!(image.mime);
                }
                Format::Gltf => {
                    let file = format!("{stem}.{}.{}", image.suffix, extension_of(&image.mime));
                    entry["uri"] = json!(uri_escape(&file));
                    entry["mimeType"] = json!(image.mime);
                    files.push((file, image.bytes));
                }
            }
        }
        align(&mut self.bin, 4);
        self.json["buffers"][0]["byteLength"] = json!(self.bin.len());
        match format {
            Format::Glb => {
                let json = serde_json::to_vec(&self.json).context("serializing the glTF JSON")?;
                files.insert(0, (format!("{stem}.glb"), super::glb::encode(&json, &self.bin)));
            }
            Format::Gltf => {
                let bin_name = format!("{stem}.bin");
                self.json["buffers"][0]["uri"] = json!(uri_escape(&bin_name));
                let json = serde_json::to_vec_pretty(&self.json).context("serializing the glTF JSON")?;
                files.insert(0, (bin_name, self.bin));
                files.insert(0, (format!("{stem}.gltf"), json));
            }
        }
        Ok(files)
    }
}

pub(crate) fn align(bytes: &mut Vec<u8>, to: usize) {
    while !bytes.len().is_multiple_of(to) {
        bytes.push(0);
    }
}

fn sniff_image_mime(bytes: &[u8]) -> Option<&'static str> {
    if bytes.starts_with(b"\x89PNG\r\n\x1a\n") {
        Some("image/png")
    } else if bytes.starts_with(&[0xFF, 0xD8, 0xFF]) {
        Some("image/jpeg")
    } else if bytes.len() >= 12 && &bytes[0..4] == b"RIFF" && &bytes[8..12] == b"WEBP" {
        Some("image/webp")
    } else if crate::asset::ktx2::is_ktx2(bytes) {
        Some("image/ktx2")
    } else {
        None
    }
}

fn extension_of(mime: &str) -> &str {
    match mime {
        "image/png" => "png",
        "image/jpeg" => "jpg",
        "image/webp" => "webp",
        "image/ktx2" => "ktx2",
        _ => "bin",
    }
}

/// A file name as a relative URI: everything but RFC 3986's unreserved
/// characters percent-encoded.
pub fn uri_escape(name: &str) -> String {
    let mut out = String::with_capacity(name.len());
    for byte in name.bytes() {
        if byte.is_ascii_alphanumeric() || b"-._~".contains(&byte) {
            out.push(byte as char);
        } else {
            out.push_str(&format!("%{byte:02X}"));
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn uris_escape_spaces_and_non_ascii() {
        assert_eq!(uri_escape("a b.lightmap0.png"), "a%20b.lightmap0.png");
        assert_eq!(uri_escape("ä#.bin"), "%C3%A4%23.bin");
    }
}
