//! The crate's integration tests, one module per concern, compiled as one test binary (one
//! link instead of one per file keeps CI's build short).

mod allocation;
mod closed_forms;
mod convergence;
mod metallic_roughness;
mod normal_maps;
mod pixel_behaviour;
mod pixel_exact;
mod reproducible;
mod runtime_compressed;
mod runtime_kernels;
mod runtime_threads;
mod vertex_antialias;
mod vertex_compressed;
mod vertex_convergence;
mod vertex_exactness;
mod vertex_highlight;
mod vertex_weld;
