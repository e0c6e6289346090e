//! PRT baker: scene loading, ray queries, BRDF families and bases, bakers, reference path
//! tracer. See docs/ for the mathematics and conventions.

pub mod accel;
pub mod basis;
pub mod brdf;
pub mod config;
pub mod integrator;
pub mod lights;
pub mod metrics;
pub mod pixel;
pub mod pixel_compress;
pub mod reference;
pub mod run;
pub mod sampling;
pub mod scene;
pub mod testing;

/// The former home of [`metrics::relative_l2`], kept while the workspace's `tests` crate
/// imports it from here.
#[doc(hidden)]
pub mod report_pixel {
    pub use crate::metrics::relative_l2;
}
