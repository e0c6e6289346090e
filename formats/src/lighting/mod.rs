//! The lighting bases of the per-vertex mode, shared by the baker and the runtime so that both
//! use one definition (the conventions are written out in `docs/lighting.md`):
//!
//! * [`cubemap`]: the cube map (6 x N x N RGB texels, OpenGL face order and orientation),
//!   texel directions and exact solid angles, resampling of lat-long environments with a
//!   rotation about +Y, exact 2x downsampling, lookups.
//! * [`haar`]: the area-weighted non-standard 2D Haar wavelet transform of each cube face
//!   (orthonormal in the solid-angle metric) and its coefficient layout.
//! * [`sparse`]: the k largest terms of a coefficient vector and sparse dot products.
//! * [`sh`]: real spherical harmonics of bands 0..3 (16 coefficients): evaluation,
//!   projection of a cube map, rotation.
//! * [`prefilter`]: the Gaussian prefilter of the specular-lobe split, on the cube map and as
//!   per-band SH factors.
//! * [`quadrature`]: Gauss–Legendre and exact sphere quadratures for the SH mathematics.
//!
//! Everything validates what the caller controls and returns [`LightingError`]; the
//! mathematics runs in f64 and stores f32.

pub mod cubemap;
mod error;
pub mod haar;
pub mod irradiance;
pub mod prefilter;
pub mod quadrature;
pub mod sh;
pub mod sparse;

pub use cubemap::{CubeMap, Face};
pub use error::LightingError;
pub use haar::{HaarCoefficient, HaarCube, HaarKind};
pub use sh::ShRotation;
pub use sparse::SparseVector;
