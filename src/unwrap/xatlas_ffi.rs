//! Raw declarations for the 2019 xatlas C++ API that `xatlas-rs` 0.1.3 compiles into its static
//! `libxatlas.a` (`vendor/xatlas.h` / `vendor/xatlas.cpp` of that crate; upstream is
//! <https://github.com/jpcy/xatlas>, MIT, Jonathan Young, derived from thekla_atlas and NVIDIA
//! Texture Tools).
//!
//! `xatlas-rs`'s own bindings carry MSVC symbol names and do not link on Linux, so these
//! declarations name the Itanium-mangled symbols directly (`nm --defined-only libxatlas.a`).
//! The structs are `#[repr(C)]` mirrors of the header's; their layout is checked against the
//! header (as compiled by g++ for x86-64 / LP64) in `tests/unwrap.rs`.
//!
//! Everything here is raw: the safe wrapper is the private module `unwrap::xatlas`, used through
//! [`super::run`] with [`super::Backend::Xatlas`]. Nothing else belongs in
//! this file.
#![allow(non_snake_case, missing_docs)]

use std::ffi::{c_char, c_int, c_void};

// Link the static library that xatlas-rs's build script compiles, although none of the crate's
// Rust items are used.
use xatlas_rs as _;

/// `xatlas::Chart`: a group of connected faces belonging to one (sub-)atlas.
#[repr(C)]
#[derive(Debug, Clone, Copy)]
pub struct Chart {
    /// Sub-atlas index.
    pub atlasIndex: u32,
    /// `indexCount` indices into the owning [`Mesh::vertexArray`].
    pub indexArray: *mut u32,
    pub indexCount: u32,
}

/// `xatlas::Vertex`: one output vertex.
#[repr(C)]
#[derive(Debug, Clone, Copy)]
pub struct Vertex {
    /// Sub-atlas index; -1 if the vertex belongs to no chart (ignored / degenerate faces).
    pub atlasIndex: i32,
    /// Not normalized: texel units of [`Atlas::width`] × [`Atlas::height`].
    pub uv: [f32; 2],
    /// Index of the input vertex this output vertex was created from.
    pub xref: u32,
}

/// `xatlas::Mesh`: one output mesh, one per `AddMesh` call.
#[repr(C)]
#[derive(Debug, Clone, Copy)]
pub struct Mesh {
    pub chartArray: *mut Chart,
    pub chartCount: u32,
    /// Same triangles in the same order as the input, indexing `vertexArray`.
    pub indexArray: *mut u32,
    pub indexCount: u32,
    pub vertexArray: *mut Vertex,
    pub vertexCount: u32,
}

/// `xatlas::Atlas`: empty on creation, populated by `PackCharts`.
#[repr(C)]
#[derive(Debug, Clone, Copy)]
pub struct Atlas {
    /// Atlas width in texels.
    pub width: u32,
    /// Atlas height in texels.
    pub height: u32,
    /// Number of sub-atlases (0 or 1 unless `PackOptions::resolution` is non-zero).
    pub atlasCount: u32,
    /// Total number of charts in all meshes.
    pub chartCount: u32,
    /// Number of output meshes (= number of `AddMesh` calls).
    pub meshCount: u32,
    /// `meshCount` output meshes.
    pub meshes: *mut Mesh,
    /// `atlasCount` normalized texel utilizations.
    pub utilization: *mut f32,
    /// `PackOptions::texelsPerUnit` if > 0, otherwise the estimate used.
    pub texelsPerUnit: f32,
}

/// `xatlas::IndexFormat::Enum`.
pub type IndexFormat = u32;
pub const INDEX_FORMAT_UINT16: IndexFormat = 0;
pub const INDEX_FORMAT_UINT32: IndexFormat = 1;

/// `xatlas::AddMeshError::Enum`.
pub type AddMeshError = u32;
pub const ADD_MESH_SUCCESS: AddMeshError = 0;

/// `xatlas::ProgressCategory::Enum`.
pub type ProgressCategory = u32;

/// `xatlas::MeshDecl`: input mesh declaration. The data is copied by `AddMesh`.
#[repr(C)]
#[derive(Debug, Clone, Copy)]
pub struct MeshDecl {
    pub vertexCount: u32,
    pub vertexPositionData: *const c_void,
    /// Bytes between consecutive positions (three `f32`s each).
    pub vertexPositionStride: u32,
    pub vertexNormalData: *const c_void,
    pub vertexNormalStride: u32,
    pub vertexUvData: *const c_void,
    pub vertexUvStride: u32,
    /// 0 means "not indexed": every three vertices form a triangle.
    pub indexCount: u32,
    pub indexData: *const c_void,
    pub indexOffset: i32,
    pub indexFormat: IndexFormat,
    /// `indexCount / 3` flags; faces set to true get no chart.
    pub faceIgnoreData: *const bool,
}

impl Default for MeshDecl {
    /// The header's default member initializers.
    fn default() -> Self {
        MeshDecl {
            vertexCount: 0,
            vertexPositionData: std::ptr::null(),
            vertexPositionStride: 0,
            vertexNormalData: std::ptr::null(),
            vertexNormalStride: 0,
            vertexUvData: std::ptr::null(),
            vertexUvStride: 0,
            indexCount: 0,
            indexData: std::ptr::null(),
            indexOffset: 0,
            indexFormat: INDEX_FORMAT_UINT16,
            faceIgnoreData: std::ptr::null(),
        }
    }
}

/// `xatlas::ChartOptions`, passed by value (trivially copyable).
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ChartOptions {
    /// Don't grow charts larger than this (world units²). 0: no limit.
    pub maxChartArea: f32,
    /// Don't grow charts with a longer boundary than this. 0: no limit.
    pub maxBoundaryLength: f32,
    pub proxyFitMetricWeight: f32,
    pub roundnessMetricWeight: f32,
    pub straightnessMetricWeight: f32,
    pub normalSeamMetricWeight: f32,
    pub textureSeamMetricWeight: f32,
    pub maxThreshold: f32,
    pub growFaceCount: u32,
    pub maxIterations: u32,
}

impl Default for ChartOptions {
    /// The header's default member initializers.
    fn default() -> Self {
        ChartOptions {
            maxChartArea: 0.0,
            maxBoundaryLength: 0.0,
            proxyFitMetricWeight: 2.0,
            roundnessMetricWeight: 0.01,
            straightnessMetricWeight: 6.0,
            normalSeamMetricWeight: 4.0,
            textureSeamMetricWeight: 0.5,
            maxThreshold: 2.0,
            growFaceCount: 32,
            maxIterations: 1,
        }
    }
}

/// `xatlas::PackOptions`, passed by value (trivially copyable).
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PackOptions {
    /// Random placement attempts per chart; 0 = brute force.
    pub attempts: c_int,
    /// Texels per world unit; 0 = estimate from `resolution`.
    pub texelsPerUnit: f32,
    /// 0: one atlas that grows to fit; otherwise one or more atlases of exactly this size.
    pub resolution: u32,
    /// Charts larger than this (texels) are scaled down.
    pub maxChartSize: u32,
    /// Align charts to 4×4 blocks.
    pub blockAlign: bool,
    /// Rasterize charts conservatively and dilate them by `padding`.
    pub conservative: bool,
    /// Texels of dilation; only used with `conservative`.
    pub padding: u32,
}

impl Default for PackOptions {
    /// The header's default member initializers.
    fn default() -> Self {
        PackOptions {
            attempts: 4096,
            texelsPerUnit: 0.0,
            resolution: 0,
            maxChartSize: 1024,
            blockAlign: false,
            conservative: false,
            padding: 0,
        }
    }
}

/// `xatlas::ProgressFunc`.
pub type ProgressFunc = Option<unsafe extern "C" fn(category: ProgressCategory, progress: c_int, user: *mut c_void)>;

/// `xatlas::ParameterizeFunc`.
pub type ParameterizeFunc = Option<
    unsafe extern "C" fn(
        positions: *const f32,
        texcoords: *mut f32,
        vertex_count: u32,
        indices: *const u32,
        index_count: u32,
        is_planar: bool,
    ),
>;

/// `xatlas::PrintFunc` (`int (*)(const char *, ...)`). Only ever passed as `None` here.
pub type PrintFunc = Option<unsafe extern "C" fn(format: *const c_char, ...) -> c_int>;

unsafe extern "C" {
    /// `xatlas::Create()`: a new, empty atlas (never null).
    #[link_name = "_ZN6xatlas6CreateEv"]
    pub fn Create() -> *mut Atlas;

    /// `xatlas::Destroy(Atlas*)`: frees the atlas and everything it returned.
    #[link_name = "_ZN6xatlas7DestroyEPNS_5AtlasE"]
    pub fn Destroy(atlas: *mut Atlas);

    /// `xatlas::AddMesh(Atlas*, MeshDecl const&)`.
    #[link_name = "_ZN6xatlas7AddMeshEPNS_5AtlasERKNS_8MeshDeclE"]
    pub fn AddMesh(atlas: *mut Atlas, decl: *const MeshDecl) -> AddMeshError;

    /// `xatlas::ComputeCharts(Atlas*, ChartOptions, ProgressFunc, void*)`.
    #[link_name = "_ZN6xatlas13ComputeChartsEPNS_5AtlasENS_12ChartOptionsEPFvNS_16ProgressCategory4EnumEiPvES5_"]
    pub fn ComputeCharts(atlas: *mut Atlas, options: ChartOptions, progress: ProgressFunc, user: *mut c_void);

    /// `xatlas::ParameterizeCharts(Atlas*, ParameterizeFunc, ProgressFunc, void*)`.
    #[link_name = "_ZN6xatlas18ParameterizeChartsEPNS_5AtlasEPFvPKfPfjPKjjbEPFvNS_16ProgressCategory4EnumEiPvESB_"]
    pub fn ParameterizeCharts(atlas: *mut Atlas, func: ParameterizeFunc, progress: ProgressFunc, user: *mut c_void);

    /// `xatlas::PackCharts(Atlas*, PackOptions, ProgressFunc, void*)`.
    #[link_name = "_ZN6xatlas10PackChartsEPNS_5AtlasENS_11PackOptionsEPFvNS_16ProgressCategory4EnumEiPvES5_"]
    pub fn PackCharts(atlas: *mut Atlas, options: PackOptions, progress: ProgressFunc, user: *mut c_void);

    /// `xatlas::SetPrint(PrintFunc, bool)`: process-global; `None` silences all output
    /// (the default prints warnings with `printf`).
    #[link_name = "_ZN6xatlas8SetPrintEPFiPKczEb"]
    pub fn SetPrint(print: PrintFunc, verbose: bool);

    /// `xatlas::StringForEnum(AddMeshError::Enum)`: a static NUL-terminated string.
    #[link_name = "_ZN6xatlas13StringForEnumENS_12AddMeshError4EnumE"]
    pub fn StringForAddMeshError(error: AddMeshError) -> *const c_char;
}
