//! Reading accessor data: every component type, normalized integers
//! (KHR_mesh_quantization), byte strides and sparse substitution, with every
//! offset bounds-checked before anything is allocated.

use anyhow::{Result, bail, ensure};
use gltf::accessor::{DataType, Dimensions};

use super::SourceAsset;

/// An accessor without a buffer view is all zeros (plus sparse values); cap
/// what such a declaration may make us allocate.
const MAX_VIEWLESS_BYTES: usize = 256 << 20;

/// Bytes one element occupies, with the 4-byte column alignment glTF
/// requires for byte and short matrices.
pub fn element_size(accessor: &gltf::Accessor) -> usize {
    let component = accessor.data_type().size();
    match (accessor.dimensions(), component) {
        (Dimensions::Mat2, 1) => 8,
        (Dimensions::Mat3, 1) => 12,
        (Dimensions::Mat3, 2) => 24,
        (dimensions, _) => dimensions.multiplicity() * component,
    }
}

/// The accessor's elements packed tightly (`count × element_size` bytes),
/// sparse values applied.
pub fn packed_bytes(asset: &SourceAsset, accessor: &gltf::Accessor) -> Result<Vec<u8>> {
    let size = element_size(accessor);
    let count = accessor.count();
    let label = format!("accessor {}", accessor.index());
    let mut out = match accessor.view() {
        Some(view) => {
            let bytes = asset.view_bytes(&view)?;
            let stride = view.stride().unwrap_or(size);
            ensure!(stride >= size, "{label}: byteStride {stride} is smaller than its element ({size} bytes)");
            if count > 0 {
                let end = (count - 1)
                    .checked_mul(stride)
                    .and_then(|v| v.checked_add(accessor.offset()))
                    .and_then(|v| v.checked_add(size));
                match end {
                    Some(end) if end <= bytes.len() => {}
                    _ => bail!(
                        "{label}: {count} elements of {size} bytes (stride {stride}, offset {}) run past the end of bufferView {} ({} bytes)",
                        accessor.offset(),
                        view.index(),
                        bytes.len()
                    ),
                }
            }
            let mut out = Vec::with_capacity(count * size);
            for i in 0..count {
                let start = accessor.offset() + i * stride;
                out.extend_from_slice(&bytes[start..start + size]);
            }
            out
        }
        None => {
            let total = count.checked_mul(size).filter(|&t| t <= MAX_VIEWLESS_BYTES);
            match total {
                Some(total) => vec![0u8; total],
                None => bail!(
                    "{label}: {count} elements of {size} bytes with no bufferView (zeros, plus sparse values) \
                     exceed the {} MiB bake accepts",
                    MAX_VIEWLESS_BYTES >> 20
                ),
            }
        }
    };
    if let Some(sparse) = accessor.sparse() {
        let n = sparse.count();
        ensure!(n <= count, "{label}: sparse count {n} exceeds the accessor's count {count}");
        let indices = sparse.indices();
        let index_bytes = asset.view_bytes(&indices.view())?;
        let index_size = match indices.index_type() {
            gltf::accessor::sparse::IndexType::U8 => 1,
            gltf::accessor::sparse::IndexType::U16 => 2,
            gltf::accessor::sparse::IndexType::U32 => 4,
        };
        let values = sparse.values();
        let value_bytes = asset.view_bytes(&values.view())?;
        let fits = |offset: usize, bytes: usize, len: usize| offset.checked_add(bytes).is_some_and(|end| end <= len);
        ensure!(
            fits(indices.offset(), n * index_size, index_bytes.len())
                && fits(values.offset(), n * size, value_bytes.len()),
            "{label}: sparse data runs past the end of its bufferView"
        );
        for k in 0..n {
            let at = indices.offset() + k * index_size;
            let target = match index_size {
                1 => index_bytes[at] as usize,
                2 => u16::from_le_bytes([index_bytes[at], index_bytes[at + 1]]) as usize,
                _ => u32::from_le_bytes(index_bytes[at..at + 4].try_into().unwrap()) as usize,
            };
            ensure!(target < count, "{label}: sparse index {target} is past its count {count}");
            let from = values.offset() + k * size;
            out[target * size..(target + 1) * size].copy_from_slice(&value_bytes[from..from + size]);
        }
    }
    Ok(out)
}

/// The accessor as floats, `multiplicity` per element, with normalized
/// integers mapped to [0,1] or [-1,1] as the glTF spec defines.
pub fn read_floats(asset: &SourceAsset, accessor: &gltf::Accessor) -> Result<Vec<f32>> {
    ensure!(
        !matches!(accessor.dimensions(), Dimensions::Mat2 | Dimensions::Mat3),
        "accessor {}: matrix accessors are not read as vertex data",
        accessor.index()
    );
    let bytes = packed_bytes(asset, accessor)?;
    let normalized = accessor.normalized();
    let values = match accessor.data_type() {
        DataType::F32 => bytes.chunks_exact(4).map(|c| f32::from_le_bytes(c.try_into().unwrap())).collect(),
        DataType::U8 => bytes.iter().map(|&c| if normalized { c as f32 / 255.0 } else { c as f32 }).collect(),
        DataType::I8 => bytes
            .iter()
            .map(|&c| {
                let c = c as i8 as f32;
                if normalized { (c / 127.0).max(-1.0) } else { c }
            })
            .collect(),
        DataType::U16 => bytes
            .chunks_exact(2)
            .map(|c| {
                let c = u16::from_le_bytes([c[0], c[1]]) as f32;
                if normalized { c / 65535.0 } else { c }
            })
            .collect(),
        DataType::I16 => bytes
            .chunks_exact(2)
            .map(|c| {
                let c = i16::from_le_bytes([c[0], c[1]]) as f32;
                if normalized { (c / 32767.0).max(-1.0) } else { c }
            })
            .collect(),
        DataType::U32 => bytes.chunks_exact(4).map(|c| u32::from_le_bytes(c.try_into().unwrap()) as f32).collect(),
    };
    Ok(values)
}

/// The accessor as vectors of `N` floats; errors if it has another width.
pub fn read_vectors<const N: usize>(asset: &SourceAsset, accessor: &gltf::Accessor) -> Result<Vec<[f32; N]>> {
    let width = accessor.dimensions().multiplicity();
    ensure!(width == N, "accessor {}: expected {N} components, found {width}", accessor.index());
    let floats = read_floats(asset, accessor)?;
    Ok(floats.chunks_exact(N).map(|c| c.try_into().unwrap()).collect())
}

/// An index accessor (unsigned byte, short or int scalars) as u32.
pub fn read_indices(asset: &SourceAsset, accessor: &gltf::Accessor) -> Result<Vec<u32>> {
    ensure!(
        accessor.dimensions() == Dimensions::Scalar
            && matches!(accessor.data_type(), DataType::U8 | DataType::U16 | DataType::U32),
        "accessor {}: indices must be unsigned scalars",
        accessor.index()
    );
    let bytes = packed_bytes(asset, accessor)?;
    Ok(match accessor.data_type() {
        DataType::U8 => bytes.iter().map(|&b| b as u32).collect(),
        DataType::U16 => bytes.chunks_exact(2).map(|c| u16::from_le_bytes([c[0], c[1]]) as u32).collect(),
        _ => bytes.chunks_exact(4).map(|c| u32::from_le_bytes(c.try_into().unwrap())).collect(),
    })
}
