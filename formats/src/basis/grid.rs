//! The node grid of the basis tables: what its three angular coordinates are ([`GridKind`]),
//! how many nodes each axis has ([`AngularGrid`], [`GridSpec`]) and the direction pair each
//! node stands for ([`GridNode`], computed in f64 on the baker side).

use serde::{Deserialize, Serialize};

use super::{BasisError, HALF_DIFF_COS_OFFSET};

/// What the three axes of an [`AngularGrid`] are (see the [`basis`](super) module docs).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum GridKind {
    /// `(theta_i, theta_o, phi)`, uniform, horizon nodes included (the thesis' grid; the only
    /// meaning in schema 1, hence the default of a missing field).
    #[default]
    Angles,
    /// `(theta_h, theta_d, phi_d)` graded towards the specular peak and the grazing limit.
    HalfDiff,
}

impl GridKind {
    /// The serialized spelling (`angles`, `half-diff`), also used in messages.
    pub fn name(self) -> &'static str {
        match self {
            GridKind::Angles => "angles",
            GridKind::HalfDiff => "half-diff",
        }
    }

    /// Names of the three axes.
    pub fn axis_names(self) -> [&'static str; 3] {
        match self {
            GridKind::Angles => ["theta_i", "theta_o", "phi"],
            GridKind::HalfDiff => ["theta_h", "theta_d", "phi_d"],
        }
    }
}

/// Node counts of the isotropic three-axis grid (see the [`basis`](super) module docs). The
/// field names are those of the [`GridKind::Angles`] axes; for [`GridKind::HalfDiff`] they
/// count the nodes along `theta_h`, `theta_d` and `phi_d`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct AngularGrid {
    /// Nodes along the first axis (`theta_i`, or `theta_h`); at least 2.
    pub n_theta_i: usize,
    /// Nodes along the second axis (`theta_o`, or `theta_d`); at least 2.
    pub n_theta_o: usize,
    /// Nodes along the third axis (`phi`, or `phi_d`); at least 2.
    pub n_phi: usize,
}

/// A grid: what its axes are and how many nodes each has.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct GridSpec {
    /// What the axes are.
    pub kind: GridKind,
    /// How many nodes each axis has.
    pub dims: AngularGrid,
}

impl GridSpec {
    /// The default grid of new bases: [`GridKind::HalfDiff`], [`AngularGrid::HALF_DIFF`].
    pub const DEFAULT: GridSpec = GridSpec {
        kind: GridKind::HalfDiff,
        dims: AngularGrid::HALF_DIFF,
    };

    /// The thesis' grid: [`GridKind::Angles`], [`AngularGrid::THESIS`].
    pub const THESIS: GridSpec = GridSpec {
        kind: GridKind::Angles,
        dims: AngularGrid::THESIS,
    };

    /// A grid of `kind` with node counts `dims`.
    pub fn new(kind: GridKind, dims: AngularGrid) -> GridSpec {
        GridSpec { kind, dims }
    }

    /// Number of nodes ([`AngularGrid::len`]).
    pub fn len(&self) -> usize {
        self.dims.len()
    }

    /// Whether the grid has no nodes (never the case for a valid grid).
    pub fn is_empty(&self) -> bool {
        self.dims.is_empty()
    }

    /// The direction pair of node `(i, o, k)`.
    pub fn node(&self, i: usize, o: usize, k: usize) -> GridNode {
        self.dims.node(self.kind, i, o, k)
    }

    /// All nodes in table order ([`AngularGrid::index`]).
    pub fn nodes(&self) -> Vec<GridNode> {
        let g = &self.dims;
        let mut v = Vec::with_capacity(g.len());
        for i in 0..g.n_theta_i {
            for o in 0..g.n_theta_o {
                for k in 0..g.n_phi {
                    v.push(self.node(i, o, k));
                }
            }
        }
        v
    }

    /// e.g. `half-diff 96x64x8`.
    pub fn describe(&self) -> String {
        format!(
            "{} {}x{}x{}",
            self.kind.name(),
            self.dims.n_theta_i,
            self.dims.n_theta_o,
            self.dims.n_phi
        )
    }
}

/// A direction pair standing for one grid node (f64, baker side): cosines of `theta_i`,
/// `theta_o`, of the azimuth difference `phi` and of `theta_h`. For [`GridKind::HalfDiff`]
/// nodes outside the pair of hemispheres the cosines are returned unclamped (negative); the
/// tables hold the lobe continued with clamped cosines there.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GridNode {
    /// Cosine of the polar angle of `wi` (its z in the local frame).
    pub cos_theta_i: f64,
    /// Cosine of the polar angle of `wo`.
    pub cos_theta_o: f64,
    /// Cosine of the angle between the tangent-plane projections of `wi` and `wo`.
    pub cos_phi: f64,
    /// Cosine of the polar angle of the half vector.
    pub cos_theta_h: f64,
}

impl GridNode {
    /// Whether both directions are above the horizon (weight > 0 in the error metric).
    pub fn inside(&self) -> bool {
        self.cos_theta_i > 0.0 && self.cos_theta_o > 0.0
    }
}

impl AngularGrid {
    /// The thesis' resolution (section 4.1.5): 30 x 30 x 60 over `(theta_i, theta_o, phi)`.
    pub const THESIS: AngularGrid = AngularGrid {
        n_theta_i: 30,
        n_theta_o: 30,
        n_phi: 60,
    };

    /// The default [`GridKind::HalfDiff`] resolution: 96 `theta_h` x 64 `theta_d` x 8 `phi_d`
    /// nodes (49152, fewer than [`AngularGrid::THESIS`]'s 54000).
    pub const HALF_DIFF: AngularGrid = AngularGrid {
        n_theta_i: 96,
        n_theta_o: 64,
        n_phi: 8,
    };

    /// Number of nodes (product of the three axis sizes).
    pub fn len(&self) -> usize {
        self.n_theta_i * self.n_theta_o * self.n_phi
    }

    /// Whether the grid has no nodes (never the case for a valid grid).
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// theta of node `j` on an [`GridKind::Angles`] theta axis with `n` nodes.
    pub fn theta(n: usize, j: usize) -> f64 {
        j as f64 * std::f64::consts::FRAC_PI_2 / (n - 1) as f64
    }

    /// phi of node `k` on an [`GridKind::Angles`] phi axis with `n` nodes.
    pub fn phi(n: usize, k: usize) -> f64 {
        k as f64 * std::f64::consts::PI / (n - 1) as f64
    }

    /// Flat node index (basis index excluded).
    #[inline]
    pub fn index(&self, i: usize, o: usize, k: usize) -> usize {
        (i * self.n_theta_o + o) * self.n_phi + k
    }

    /// The direction pair of node `(i, o, k)` for a grid of kind `kind`.
    pub fn node(&self, kind: GridKind, i: usize, o: usize, k: usize) -> GridNode {
        match kind {
            GridKind::Angles => {
                let (si, ci) = Self::theta(self.n_theta_i, i).sin_cos();
                let (so, co) = Self::theta(self.n_theta_o, o).sin_cos();
                let cp = Self::phi(self.n_phi, k).cos();
                let h = [si + so * cp, so * (1.0 - cp * cp).max(0.0).sqrt(), ci + co];
                let len = (h[0] * h[0] + h[1] * h[1] + h[2] * h[2]).sqrt();
                GridNode {
                    cos_theta_i: ci,
                    cos_theta_o: co,
                    cos_phi: cp,
                    cos_theta_h: if len > 0.0 { h[2] / len } else { 0.0 },
                }
            }
            GridKind::HalfDiff => {
                let u = |j: usize, n: usize| j as f64 / (n - 1) as f64;
                let (ch, cd, s2) =
                    half_diff_node(u(i, self.n_theta_i), u(o, self.n_theta_o), u(k, self.n_phi));
                half_diff_pair(ch, cd, s2)
            }
        }
    }

    /// Checks that every axis has at least 2 nodes (interpolation needs both ends).
    pub fn validate(&self) -> Result<(), BasisError> {
        if self.n_theta_i < 2 || self.n_theta_o < 2 || self.n_phi < 2 {
            return Err(BasisError::Invalid(format!(
                "angular grid {}x{}x{} needs at least 2 nodes per axis",
                self.n_theta_i, self.n_theta_o, self.n_phi
            )));
        }
        Ok(())
    }
}

/// `(cos theta_h, cos theta_d, sin^2 phi_d)` at the [`GridKind::HalfDiff`] coordinates
/// `(u1, u2, u3)` (the inverse of the evaluation's mapping).
pub fn half_diff_node(u1: f64, u2: f64, u3: f64) -> (f64, f64, f64) {
    let c0 = HALF_DIFF_COS_OFFSET;
    let cos_h = 1.0 - u1.powi(4);
    let cos_d = ((1.0 + c0) * (u2 * (c0 / (1.0 + c0)).ln()).exp() - c0).clamp(0.0, 1.0);
    (cos_h.clamp(0.0, 1.0), cos_d, u3.clamp(0.0, 1.0))
}

/// The direction pair with half vector at polar angle `theta_h` (azimuth 0) and `wi` at
/// `(theta_d, phi_d)` about it (`wo` is `wi` mirrored about the half vector), given
/// `cos theta_h`, `cos theta_d` and `sin^2 phi_d` (`phi_d` in `[0, pi/2]`).
pub fn half_diff_pair(cos_h: f64, cos_d: f64, sin2_phi_d: f64) -> GridNode {
    let sh = (1.0 - cos_h * cos_h).max(0.0).sqrt();
    let sd = (1.0 - cos_d * cos_d).max(0.0).sqrt();
    let sp = sin2_phi_d.clamp(0.0, 1.0).sqrt();
    let cp = (1.0 - sin2_phi_d).clamp(0.0, 1.0).sqrt();
    // wi = R_y(theta_h) (sd cp, sd sp, cd); wo = 2 cd h - wi with h = (sh, 0, ch)
    let wi = [
        cos_h * sd * cp + sh * cos_d,
        sd * sp,
        -sh * sd * cp + cos_h * cos_d,
    ];
    let wo = [
        2.0 * cos_d * sh - wi[0],
        -wi[1],
        2.0 * cos_d * cos_h - wi[2],
    ];
    let li = (wi[0] * wi[0] + wi[1] * wi[1]).sqrt();
    let lo = (wo[0] * wo[0] + wo[1] * wo[1]).sqrt();
    let cos_phi = if li * lo > 1e-300 {
        ((wi[0] * wo[0] + wi[1] * wo[1]) / (li * lo)).clamp(-1.0, 1.0)
    } else {
        1.0
    };
    GridNode {
        cos_theta_i: wi[2],
        cos_theta_o: wo[2],
        cos_phi,
        cos_theta_h: cos_h,
    }
}
