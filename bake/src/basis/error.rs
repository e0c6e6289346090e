//! The error type of basis construction and measurement.

/// Why a basis could not be configured, built or measured.
#[derive(Debug, thiserror::Error)]
pub enum BasisError {
    #[error("the diffuse family needs no basis: it is basis 0 alone")]
    DiffuseFamily,
    #[error("invalid parameter range [{lo}, {hi}]")]
    InvalidRange { lo: f64, hi: f64 },
    #[error("parameter range [{lo}, {hi}] is outside the {family} family's domain")]
    RangeOutsideDomain {
        lo: f64,
        hi: f64,
        family: &'static str,
    },
    #[error(transparent)]
    Grid(#[from] prt_formats::basis::BasisError),
    #[error("the number of bases must be at least 1")]
    NoBases,
    #[error("need at least 2 parameter samples")]
    TooFewSamples,
    #[error("sample prior must hold one finite nonnegative weight per lobe")]
    BadPrior,
    #[error("sample prior is all zero")]
    ZeroPrior,
    #[error("lobe tables have {rows} rows, grid has {nodes} nodes")]
    TableSize { rows: usize, nodes: usize },
    #[error("no lobes to build a basis from")]
    NoLobes,
    #[error("lobe {0} has non-finite values")]
    NonFiniteLobe(usize),
    #[error("no PCA iteration ran")]
    NoIteration,
    #[error("SVD did not converge: {0}")]
    Svd(String),
    #[error("eigendecomposition did not converge: {0}")]
    Eigen(String),
}
