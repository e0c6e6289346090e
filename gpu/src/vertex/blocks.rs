//! The uniform and storage blocks the per-vertex shader reads (`shaders/vertex.wgsl`'s
//! `Frame`, `Material` and `Basis`), field for field: `#[repr(C)]` with the WGSL layout's
//! padding, so `bytemuck` uploads them as they are; and the order of the cubes in its cube
//! texture.

use prt_runtime::gpu_surface::VertexSurface;

/// `Frame` in the shader.
#[repr(C)]
#[derive(Clone, Copy, Default, bytemuck::Pod, bytemuck::Zeroable)]
pub(super) struct FrameBlock {
    pub(super) eye: [f32; 4],
    pub(super) right: [f32; 4],
    pub(super) up: [f32; 4],
    pub(super) forward: [f32; 4],
    pub(super) back: [[f32; 4]; 3],
    pub(super) tan_half_fov: f32,
    pub(super) aspect: f32,
    pub(super) near: f32,
    pub(super) turned: u32,
    pub(super) width: f32,
    pub(super) height: f32,
    pub(super) env_width: u32,
    pub(super) env_height: u32,
    pub(super) normals_at: u32,
    pub(super) uvs_at: u32,
    pub(super) materials_of_at: u32,
    pub(super) vertex_info_at: u32,
    pub(super) texture_info_at: u32,
    pub(super) cube_size_at: u32,
    /// The open sky's irradiance table among the cubes (after the prefiltered ones), or -1.
    pub(super) open_sky_cube: i32,
    /// Sub-samples per side of a background pixel (`VertexSurface::background_samples`).
    pub(super) background_samples: u32,
    /// The compact lights in `environment` (floats; 8 per light: the unturned direction, 0,
    /// the power, 0) and how many (`VertexSurface::compact_lights`).
    pub(super) lights_at: u32,
    pub(super) n_lights: u32,
    pub(super) pad: [u32; 2],
}

/// `Material` in the shader.
#[repr(C)]
#[derive(Clone, Copy, Default, bytemuck::Pod, bytemuck::Zeroable)]
pub(super) struct MaterialBlock {
    pub(super) kd: [f32; 3],
    pub(super) group: i32,
    pub(super) ks: [f32; 3],
    pub(super) texture: i32,
    pub(super) basis: i32,
    pub(super) core_at: u32,
    pub(super) taps_len: u32,
    pub(super) tap0: u32,
    pub(super) tap0_w: f32,
    pub(super) tap1: u32,
    pub(super) tap1_w: f32,
    pub(super) normal_map: i32,
    /// Its family (`FAMILY_*` in the shader) and parameter, for the compact lights' true lobe.
    pub(super) family: u32,
    pub(super) param: f32,
    pub(super) pad: [u32; 2],
}

/// The shader's code of a family (`FAMILY_*` in `shaders/vertex.wgsl`).
pub(super) fn family_code(family: prt_formats::Family) -> u32 {
    match family {
        prt_formats::Family::Diffuse => 0,
        prt_formats::Family::BlinnPhong => 1,
        prt_formats::Family::Ggx => 2,
    }
}

/// `Basis` in the shader.
#[repr(C)]
#[derive(Clone, Copy, Default, bytemuck::Pod, bytemuck::Zeroable)]
pub(super) struct BasisBlock {
    pub(super) n_theta: u32,
    pub(super) n_phi: u32,
    pub(super) r_o: u32,
    pub(super) r_i: u32,
    pub(super) n_widths: u32,
    pub(super) n_dirs: u32,
    pub(super) u_o_at: u32,
    pub(super) u_o_pole_at: u32,
    pub(super) refl_at: u32,
    pub(super) refl_pole_at: u32,
    pub(super) widths_at: u32,
    pub(super) pad: u32,
}

/// The sides of the cubes the shader reads from its cube texture, in layer order (six layers
/// each): the prefiltered cubes, then the open sky's irradiance table when the light needs
/// one.
pub(super) fn cube_sizes(s: &VertexSurface) -> Vec<usize> {
    let open_sky = s
        .needs_open_sky()
        .then_some(prt_formats::lighting::irradiance::IRRADIANCE_CUBE);
    s.prefiltered()
        .iter()
        .map(|c| c.size())
        .chain(open_sky)
        .collect()
}
