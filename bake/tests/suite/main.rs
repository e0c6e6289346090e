//! The crate's integration tests, one module per concern, compiled as one test binary (one
//! link instead of one per file keeps CI's build short).

mod accel;
mod basis;
mod brdf;
mod camera;
mod emission;
mod render_analytic;
mod scene_loading;
mod shading_basis;
mod user_input;
