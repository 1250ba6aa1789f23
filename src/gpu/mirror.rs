//! Test support: a Rust struct that mirrors a WGSL struct byte for byte is
//! checked against naga's layout of the shader that declares it, so a field
//! added, reordered or retyped on one side only fails a test instead of
//! shifting every later field on the GPU.

use super::Shader;

/// Checks that `$ty`'s size and named fields match WGSL struct `$wgsl` as
/// `$shader` declares it: `assert_mirrors!(Shader::SolveDirect, "DirectParams",
/// DirectParams { point_count, row_stride })`. List every field of `$ty`
/// except padding (names starting with `_`, which are not compared).
macro_rules! assert_mirrors {
    ($shader:expr, $wgsl:literal, $ty:ty { $($field:ident),* $(,)? }) => {
        $crate::gpu::mirror::check(
            $shader,
            $wgsl,
            std::mem::size_of::<$ty>(),
            &[$((stringify!($field), std::mem::offset_of!($ty, $field))),*],
        )
    };
}
pub(crate) use assert_mirrors;

/// Panics, naming the struct and the member, where `size` or `fields` (name
/// and byte offset) differ from naga's layout of `wgsl` in `shader`. WGSL
/// members whose names start with `_` are padding and need no Rust field.
pub(crate) fn check(shader: Shader, wgsl: &str, size: usize, fields: &[(&str, usize)]) {
    let source = shader.source();
    let module = naga::front::wgsl::parse_str(&source).unwrap_or_else(|e| panic!("{}: {e}", shader.stem()));
    let (members, span) = module
        .types
        .iter()
        .find_map(|(_, ty)| match &ty.inner {
            naga::TypeInner::Struct { members, span } if ty.name.as_deref() == Some(wgsl) => Some((members, *span)),
            _ => None,
        })
        .unwrap_or_else(|| panic!("{}: no struct {wgsl}", shader.stem()));
    assert_eq!(size, span as usize, "{wgsl}: the Rust mirror is {size} bytes, WGSL's {span}");
    let wgsl_fields: Vec<(&str, usize)> = members
        .iter()
        .filter_map(|m| m.name.as_deref().map(|name| (name, m.offset as usize)))
        .filter(|(name, _)| !name.starts_with('_'))
        .collect();
    for (name, offset) in &wgsl_fields {
        let rust = fields.iter().find(|(n, _)| n == name).map(|(_, o)| *o);
        assert_eq!(rust, Some(*offset), "{wgsl}.{name}: Rust offset {rust:?}, WGSL {offset}");
    }
    for (name, _) in fields {
        assert!(wgsl_fields.iter().any(|(n, _)| n == name), "{wgsl}: Rust field {name} is not in WGSL");
    }
}

#[cfg(test)]
// The structs exist for their layout; their fields are never read.
#[allow(dead_code)]
mod tests {
    use super::*;

    #[repr(C)]
    struct Params {
        point_count: u32,
        row_stride: u32,
        light_count: u32,
        first_light: u32,
        _pad3: f32,
        listed: u32,
        _pad: [u32; 2],
    }

    #[test]
    fn a_faithful_mirror_passes() {
        assert_mirrors!(
            Shader::SolveDirect,
            "DirectParams",
            Params { point_count, row_stride, light_count, first_light, listed }
        );
    }

    #[test]
    #[should_panic(expected = "DirectParams.point_count: Rust offset Some(4), WGSL 0")]
    fn two_fields_swapped_fail() {
        #[repr(C)]
        struct Swapped {
            row_stride: u32,
            point_count: u32,
            light_count: u32,
            first_light: u32,
            _pad: [u32; 4],
        }
        assert_mirrors!(
            Shader::SolveDirect,
            "DirectParams",
            Swapped { point_count, row_stride, light_count, first_light }
        );
    }

    #[test]
    #[should_panic(expected = "the Rust mirror is 16 bytes")]
    fn a_missing_tail_fails() {
        #[repr(C)]
        struct Short {
            point_count: u32,
            row_stride: u32,
            light_count: u32,
            first_light: u32,
        }
        assert_mirrors!(
            Shader::SolveDirect,
            "DirectParams",
            Short { point_count, row_stride, light_count, first_light }
        );
    }

    #[test]
    #[should_panic(expected = "Rust field spare is not in WGSL")]
    fn a_field_wgsl_lacks_fails() {
        #[repr(C)]
        struct Extra {
            point_count: u32,
            row_stride: u32,
            light_count: u32,
            first_light: u32,
            _pad3: f32,
            listed: u32,
            spare: [u32; 2],
        }
        assert_mirrors!(
            Shader::SolveDirect,
            "DirectParams",
            Extra { point_count, row_stride, light_count, first_light, listed, spare }
        );
    }
}
