//! PRT baker: scene loading, ray queries, BRDF families and bases, bakers, reference path
//! tracer. See DESIGN.md and docs/ for the mathematics and conventions.

pub mod bench;
pub mod brdf;
pub mod scene;
pub mod config;
pub mod accel;
pub mod integrator;
pub mod lights;
pub mod sampling;
pub mod pixel;
pub mod pixel_compress;
pub mod reference;
pub mod run;
pub mod testing;
pub mod basis;
pub mod plot;
pub mod report_pixel;
