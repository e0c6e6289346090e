//! BRDF bases for editable materials (thesis 4.1.2 and 5.2.2/5.3.1; the method and its
//! measurements are in docs/brdf-basis.md).
//!
//! - [`build_basis`]: PCA basis of a family (`blinn-phong`, `ggx`), persisted as
//!   [`prt_formats::basis::BrdfBasis`] (the runtime side lives there).
//! - [`select`]: the reconstruction error of a family's bases per `N_b`, and the smallest
//!   `N_b` meeting an error target (what the baker's `error_target` uses). The full error
//!   tables and the report are in the `prt-bench` crate.
//! - [`tensor`]: the family sampled as a 3-tensor `F(h, wo, wi)` (dense, or by the ring rows
//!   of an isotropic lobe); [`split`]: the specular split of it into Gaussians about the
//!   mirror direction and a residual; [`tucker`]: the Tucker decomposition (HOSVD, HOOI) and
//!   the error report with and without the split.
//! - [`shading`]: the persisted Tucker shading basis of the per-vertex mode
//!   ([`prt_formats::basis::ShadingBasis`]) built from them.

pub mod cells;
pub mod error;
pub mod grid;
pub mod linalg;
pub mod pca;
pub mod pole;
pub mod select;
pub mod shading;
pub mod split;
pub mod tensor;
pub mod tucker;

pub use error::BasisError;

use crate::brdf::Family;
use faer::Mat;
use pca::{PcaBuilder, PcaModel, PcaOptions, SampleDensity};
use prt_formats::basis::{
    AngularGrid, BrdfBasis, GridKind, GridSpec, ParamWarp, BASIS_SCHEMA_VERSION,
};
use rayon::prelude::*;
use std::f64::consts::FRAC_1_PI;

/// A family's parameter space: which lobe, over what range, interpolated in what warp.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FamilySpec {
    pub family: Family,
    /// Sampled `[min, max]` of the lobe parameter.
    pub range: (f64, f64),
    pub warp: ParamWarp,
}

impl FamilySpec {
    /// Defaults: Blinn-Phong s in [1, 200] (thesis), warp ln(s + 1); GGX alpha in [0.02, 1],
    /// warp ln(alpha).
    pub fn default_for(family: Family) -> Result<FamilySpec, BasisError> {
        match family {
            Family::BlinnPhong => Ok(FamilySpec {
                family,
                range: (1.0, 200.0),
                warp: ParamWarp::Log { offset: 1.0 },
            }),
            Family::Ggx => Ok(FamilySpec {
                family,
                range: (0.02, 1.0),
                warp: ParamWarp::Log { offset: 0.0 },
            }),
            Family::Diffuse => Err(BasisError::DiffuseFamily),
        }
    }

    /// Same family and warp over another range; checks that the range is usable.
    pub fn with_range(mut self, lo: f64, hi: f64) -> Result<FamilySpec, BasisError> {
        if !(lo.is_finite() && hi.is_finite() && lo < hi) {
            return Err(BasisError::InvalidRange { lo, hi });
        }
        let min_ok = match self.family {
            Family::BlinnPhong => lo >= 0.0,
            Family::Ggx => lo > 0.0,
            Family::Diffuse => false,
        };
        if !min_ok {
            return Err(BasisError::RangeOutsideDomain {
                lo,
                hi,
                family: self.family.name(),
            });
        }
        self.range = (lo, hi);
        Ok(self)
    }
}

/// Everything that determines a basis.
#[derive(Clone, Debug, PartialEq)]
pub struct BasisConfig {
    pub spec: FamilySpec,
    /// Node counts of the table grid's three axes (see `grid_kind`).
    pub grid: AngularGrid,
    /// What the grid's axes are.
    pub grid_kind: GridKind,
    /// Lobes sampled (uniformly in the warped parameter) to build the basis; also the
    /// coefficient table's resolution.
    pub param_samples: usize,
    /// `N_b`, Lambert basis included.
    pub num_bases: usize,
    pub options: PcaOptions,
}

impl BasisConfig {
    /// Our default configuration for a family: the half/difference grid 96x64x8
    /// ([`GridSpec::DEFAULT`]), 256 parameter samples.
    pub fn new(family: Family, num_bases: usize) -> Result<BasisConfig, BasisError> {
        Ok(BasisConfig {
            spec: FamilySpec::default_for(family)?,
            grid: GridSpec::DEFAULT.dims,
            grid_kind: GridSpec::DEFAULT.kind,
            param_samples: 256,
            num_bases,
            options: PcaOptions::ours(),
        })
    }

    /// The table grid (kind and sizes).
    pub fn grid_spec(&self) -> GridSpec {
        GridSpec::new(self.grid_kind, self.grid)
    }

    /// Sets the table grid.
    pub fn with_grid(mut self, grid: GridSpec) -> BasisConfig {
        self.grid = grid.dims;
        self.grid_kind = grid.kind;
        self
    }

    fn check(&self) -> Result<(), BasisError> {
        self.grid.validate()?;
        if self.num_bases == 0 {
            return Err(BasisError::NoBases);
        }
        if self.param_samples < 2 {
            return Err(BasisError::TooFewSamples);
        }
        FamilySpec::with_range(self.spec, self.spec.range.0, self.spec.range.1).map(|_| ())
    }
}

/// Prior weight of each build sample (placed uniformly in the warped parameter `u`): 1 for
/// [`SampleDensity::Warped`]; `dp/du` times the trapezoid width for [`SampleDensity::Param`].
pub fn sample_prior(spec: &FamilySpec, params: &[f64], density: SampleDensity) -> Vec<f64> {
    let n = params.len();
    match density {
        SampleDensity::Warped => vec![1.0; n],
        SampleDensity::Param => params
            .iter()
            .enumerate()
            .map(|(j, &p)| {
                let dpdu = match spec.warp {
                    ParamWarp::Linear => 1.0,
                    ParamWarp::Log { offset } => p + offset as f64,
                };
                let end = if n > 1 && (j == 0 || j == n - 1) {
                    0.5
                } else {
                    1.0
                };
                dpdu * end
            })
            .collect(),
    }
}

/// Tabulated build lobes plus the reusable PCA state, so bases of several sizes can be built
/// from one tabulation.
pub struct BasisBuilder {
    pub config: BasisConfig,
    pub params: Vec<f64>,
    pub lobes: Mat<f64>,
    pub pca: PcaBuilder,
}

impl BasisBuilder {
    pub fn new(config: BasisConfig) -> Result<BasisBuilder, BasisError> {
        config.check()?;
        let params = grid::param_samples(config.spec.range, config.spec.warp, config.param_samples);
        let g = config.grid_spec();
        let lobes = grid::tabulate(config.spec.family, &g, &params);
        let prior = sample_prior(&config.spec, &params, config.options.density);
        let pca = PcaBuilder::with_prior(lobes.as_ref(), g, config.options.clone(), &prior)?;
        Ok(BasisBuilder {
            config,
            params,
            lobes,
            pca,
        })
    }

    /// Builds the basis with `num_bases` bases (Lambert included).
    pub fn build(&self, num_bases: usize) -> Result<BuiltBasis, BasisError> {
        let model = self.pca.build(num_bases)?;
        // One projection per lobe, each on its own (the same bits in parallel).
        let coeffs: Vec<Vec<f64>> = (0..self.params.len())
            .into_par_iter()
            .map(|j| model.project(self.lobes.col_as_slice(j)))
            .collect();
        Ok(BuiltBasis {
            spec: self.config.spec,
            params: self.params.clone(),
            coeffs,
            model,
        })
    }
}

/// A basis in f64 with its coefficient table.
#[derive(Clone, Debug)]
pub struct BuiltBasis {
    pub spec: FamilySpec,
    pub params: Vec<f64>,
    /// Per parameter sample: `[a_0, a_1, ..]`.
    pub coeffs: Vec<Vec<f64>>,
    pub model: PcaModel,
}

impl BuiltBasis {
    pub fn num_bases(&self) -> usize {
        self.model.num_bases()
    }

    /// The persisted form (f32 tables, basis index fastest; basis 0 = 1/pi).
    pub fn to_persisted(&self) -> BrdfBasis {
        let nb = self.num_bases();
        let g = self.model.grid;
        let mut tables = Vec::with_capacity(g.len() * nb);
        for n in 0..g.len() {
            tables.push(FRAC_1_PI as f32);
            for b in &self.model.bases {
                tables.push(flush_tiny(b[n]));
            }
        }
        let o = &self.model.options;
        BrdfBasis {
            version: BASIS_SCHEMA_VERSION,
            family: self.spec.family,
            method: format!(
                "pca weighting={:?} normalize={} project_diffuse={} minimax_iters={} samples={}",
                o.weighting,
                o.normalize,
                o.project_diffuse,
                o.minimax_iters,
                self.params.len()
            ),
            param_range: [self.spec.range.0 as f32, self.spec.range.1 as f32],
            param_warp: self.spec.warp,
            param_samples: self.params.iter().map(|&p| p as f32).collect(),
            grid: g.dims,
            grid_kind: g.kind,
            num_bases: nb,
            tables,
            coefficients: self
                .coeffs
                .iter()
                .flat_map(|c| c.iter().map(|&x| flush_tiny(x)))
                .collect(),
        }
    }
}

/// f64 to f32 with magnitudes below 1e-30 flushed to zero: subnormal f32 table entries make
/// every interpolation that touches them many times slower, and carry no information next to
/// bases of unit norm.
fn flush_tiny(x: f64) -> f32 {
    if x.abs() < 1e-30 {
        0.0
    } else {
        x as f32
    }
}

/// Builds a family's basis (see [`BasisConfig::new`] for the defaults).
pub fn build_basis(config: BasisConfig) -> Result<BuiltBasis, BasisError> {
    let nb = config.num_bases;
    BasisBuilder::new(config)?.build(nb)
}
