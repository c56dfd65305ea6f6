//! Element kernels of finite-strain hyperelasticity in the total Lagrangian form, for the
//! energy-momentum midpoint step (docs/method.md, finite strain; Simo and Tarnow, ZAMP 43, 1992;
//! Gonzalez, CMAME 190, 2000; Betsch, Janz and Hesch, CMAME 335, 2018).
//!
//! Per quadrature point, with `G_a = grad_X N_a` in the reference configuration:
//!
//! ```text
//!   F_k = I + sum_a u_k,a (x) G_a,   C_k = F_k^T F_k,   F_m = (F_0 + F_1)/2,   dC = C_1 - C_0
//!   f_a = int_Omega0 F_m S_alg G_a dV                         (the algorithmic internal force)
//!   1/2 S_alg : dC = W(C_1) - W(C_0)                           (exact energy: f . (u_1 - u_0) = dW)
//! ```
//! `S_alg` is symmetric, so `sum_a f_a = 0` and `sum_a x_m,a x f_a = 0` (`x_m` the midpoint
//! positions): momentum and angular momentum are kept.
//!
//! - Saint Venant-Kirchhoff, `W = lambda/2 (tr E)^2 + mu E:E`, `E = (C - I)/2`: the midpoint
//!   `S_alg = lambda tr(E_a) I + 2 mu E_a`, `E_a = (E_0 + E_1)/2`, is exact (W is quadratic in C).
//! - Neo-Hooke, `W = mu/2 (tr C - 3) - mu ln J + lambda/2 (ln J)^2`, written as
//!   `W = mu/2 (I_1 - 3) + W^(I_3)`, `W^(I) = -mu/2 ln I + lambda/8 (ln I)^2`, `I_3 = det C`:
//!   the invariant discrete gradient (Betsch, Janz, Hesch) `S_alg = mu I + 2 g D_3`,
//!   `g = (W^(I_3,1) - W^(I_3,0)) / (I_3,1 - I_3,0)`, `D_3 = (cof C_0 + 4 cof C_a + cof C_1)/6`
//!   (Simpson's rule is exact for `d/ds det C(s) = cof C(s) : dC`, quadratic in s, so
//!   `D_3 : dC = I_3,1 - I_3,0` exactly). The quotient is taken without cancellation:
//!   `g = ln(1 + x)/x * (-mu/2 + lambda/8 (ln I_3,0 + ln I_3,1)) / I_3,0`, `x = dI_3 / I_3,0`,
//!   and `ln(1 + x)/x` by its series for small `|x|` (`x = 0` gives `g = W^'(I_3,0)`: no
//!   separate fallback is needed).
//!
//! 2D is plane strain: tensors are 3 x 3 with `F_33 = 1`, so `C_33 = 1`, `E_33 = 0` and the
//! formulas above hold unchanged (`tr C - 3 = tr C_2 - 2`, `det C = det C_2`).
//!
//! **Mean dilatation** (neo-Hooke, `formulation = "mixed"`, Q1 cells): the `lambda` term is
//! the cell's, `V = |K| lambda/2 (ln theta)^2` with the mean Jacobian
//! `theta = 1/|K| sum_q w_q J_q`, the rest (`mu/2 (I_1 - 3) - mu/2 ln I_3`) stays point-wise.
//! Its discrete gradient keeps the form above: with `V'_alg = (V(theta_1) - V(theta_0)) /
//! (theta_1 - theta_0)` and `J_1,q^2 - J_0,q^2 = D_3,q : dC_q` (Simpson),
//!
//! ```text
//!   S_alg,q = mu I + 2 (g_mu,q + kappa_q/2) D_3,q,   kappa_q = 2 V'_alg / (|K| (J_0,q + J_1,q))
//!   sum_q w_q 1/2 S_vol,q : dC_q = V'_alg sum_q w_q (J_1,q - J_0,q)/|K| = V(theta_1) - V(theta_0)
//! ```
//! (`g_mu` the point-wise `g` with `lambda = 0`): exact energy, symmetric `S_alg`, so momentum
//! and angular momentum are kept as before. Its tangent gains the rank-one coupling of the
//! cell's points through `theta_1`, `d theta_1 / d u_1,b = sum_p w_p/|K| cof(F_1,p) G_b,p`.
//!
//! The tangent `K_ab = d f_a / d u_1,b` (unsymmetric) is
//! `int [1/2 (G_a . S_alg G_b) I + B_a(F_m)^T DD 2 B_b(F_1)] dV`, with `B_a(F)` the
//! nonlinear strain-displacement matrix (engineering Voigt form of `sym(F^T (du (x) G_a))`)
//! and `DD = d S_alg / d C_1` (stress-like <- engineering strain-like Voigt).
//! Quadrature: the stiffness rule (1 point on simplices, 2 per direction on Q1 cells).

#![allow(clippy::needless_range_loop)] // index-heavy small dense linear algebra

use super::element::ElementKind;
use super::kernels::{check_len, stiffness_order, table, Material, MAX_DOFS};
use super::shape::map_gradients;

/// A 3 x 3 tensor, `t[i][j]`.
pub type Tensor = [[f64; 3]; 3];

/// The constitutive model of a body.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Model {
    /// Small-strain linear elasticity (the linear step).
    #[default]
    Linear,
    /// Compressible neo-Hooke, `W = mu/2 (tr C - 3) - mu ln J + lambda/2 (ln J)^2`.
    NeoHookean,
    /// Saint Venant-Kirchhoff, `W = lambda/2 (tr E)^2 + mu E:E`.
    SaintVenantKirchhoff,
}

impl Model {
    /// The scene's name of the model.
    pub fn name(self) -> &'static str {
        match self {
            Model::Linear => "linear",
            Model::NeoHookean => "neo_hookean",
            Model::SaintVenantKirchhoff => "saint_venant_kirchhoff",
        }
    }

    /// The model of a scene name.
    pub fn from_name(name: &str) -> Option<Model> {
        [Model::Linear, Model::NeoHookean, Model::SaintVenantKirchhoff]
            .into_iter()
            .find(|m| m.name() == name)
    }

    /// Whether the model is a finite-strain one (its bodies step with Newton).
    pub fn is_finite_strain(self) -> bool {
        self != Model::Linear
    }
}

/// A finite-strain material law: the model and its Lame parameters (built for the
/// finite-strain models; `Model::Linear` is evaluated as Saint Venant-Kirchhoff here).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Law {
    pub model: Model,
    pub lambda: f64,
    pub mu: f64,
    /// Neo-Hooke with the mean dilatation (`formulation = "mixed"`, quadrilaterals and
    /// hexahedra): the `lambda` term takes the cell's mean Jacobian (see the module doc).
    pub mean_dilatation: bool,
}

impl Law {
    pub fn new(model: Model, m: &Material) -> Law {
        Law { model, lambda: m.lambda, mu: m.mu, mean_dilatation: m.mean_dilatation }
    }
}

/// Why a kernel could not evaluate a cell: `det F <= 0` (or not finite) at a quadrature point.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Inverted {
    /// `det F` found there.
    pub det_f: f64,
    /// Which state: 0 for `u_0`, 1 for `u_1`.
    pub state: usize,
}

impl std::fmt::Display for Inverted {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "an element inverts (det F = {:e})", self.det_f)
    }
}

// ---------------------------------------------------------------------------------------------
// Point-wise tensor algebra (3 x 3, also in 2D: plane strain pads F_33 = 1).

fn identity() -> Tensor {
    [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]
}

/// `C = F^T F`.
pub fn right_cauchy_green(f: &Tensor) -> Tensor {
    let mut c = [[0.0; 3]; 3];
    for i in 0..3 {
        for j in i..3 {
            let mut s = 0.0;
            for k in 0..3 {
                s += f[k][i] * f[k][j];
            }
            c[i][j] = s;
            c[j][i] = s;
        }
    }
    c
}

pub fn det(a: &Tensor) -> f64 {
    a[0][0] * (a[1][1] * a[2][2] - a[1][2] * a[2][1])
        - a[0][1] * (a[1][0] * a[2][2] - a[1][2] * a[2][0])
        + a[0][2] * (a[1][0] * a[2][1] - a[1][1] * a[2][0])
}

/// The cofactor matrix, `cof A = det(A) A^{-T}` (quadratic in A; defined for singular A too).
pub fn cofactor(a: &Tensor) -> Tensor {
    [
        [
            a[1][1] * a[2][2] - a[1][2] * a[2][1],
            a[1][2] * a[2][0] - a[1][0] * a[2][2],
            a[1][0] * a[2][1] - a[1][1] * a[2][0],
        ],
        [
            a[0][2] * a[2][1] - a[0][1] * a[2][2],
            a[0][0] * a[2][2] - a[0][2] * a[2][0],
            a[0][1] * a[2][0] - a[0][0] * a[2][1],
        ],
        [
            a[0][1] * a[1][2] - a[0][2] * a[1][1],
            a[0][2] * a[1][0] - a[0][0] * a[1][2],
            a[0][0] * a[1][1] - a[0][1] * a[1][0],
        ],
    ]
}

fn ddot(a: &Tensor, b: &Tensor) -> f64 {
    let mut s = 0.0;
    for i in 0..3 {
        for j in 0..3 {
            s += a[i][j] * b[i][j];
        }
    }
    s
}

fn trace(a: &Tensor) -> f64 {
    a[0][0] + a[1][1] + a[2][2]
}

fn lin(a: f64, x: &Tensor, b: f64, y: &Tensor) -> Tensor {
    let mut z = [[0.0; 3]; 3];
    for i in 0..3 {
        for j in 0..3 {
            z[i][j] = a * x[i][j] + b * y[i][j];
        }
    }
    z
}

/// `ln(1 + x)/x` without cancellation (1 at x = 0).
fn log1p_over_x(x: f64) -> f64 {
    if x.abs() < 0.05 {
        // sum_k (-x)^k / (k + 1), truncation error below 0.05^14 / 15.
        let mut s = 0.0;
        let mut p = 1.0;
        for k in 0..14 {
            s += p / (k + 1) as f64;
            p *= -x;
        }
        s
    } else {
        x.ln_1p() / x
    }
}

/// The derivative of `ln(1 + x)/x`: `(x/(1 + x) - ln(1 + x))/x^2`.
fn log1p_over_x_prime(x: f64) -> f64 {
    if x.abs() < 0.05 {
        // sum_k k (-1)^k x^(k-1) / (k + 1).
        let mut s = 0.0;
        let mut p = 1.0;
        for k in 1..15 {
            s += -(k as f64) * p / (k + 1) as f64;
            p *= -x;
        }
        s
    } else {
        (x / (1.0 + x) - x.ln_1p()) / (x * x)
    }
}

/// The discrete gradient of `U(theta) = k/2 (ln theta)^2` between `theta_0` and `theta_1`,
/// `p = (U(theta_1) - U(theta_0)) / (theta_1 - theta_0) = k/2 (ln theta_0 + ln theta_1)
/// ln(1 + x)/x / theta_0` (`x = (theta_1 - theta_0)/theta_0`, no cancellation; `U'(theta_0)`
/// at `x = 0`), and its derivative in `theta_1`.
pub fn volumetric_pressure(k: f64, theta0: f64, theta1: f64) -> (f64, f64) {
    let x = (theta1 - theta0) / theta0;
    let (l0, l1) = (theta0.ln(), theta1.ln());
    let phi = log1p_over_x(x);
    let p = 0.5 * k * (l0 + l1) * phi / theta0;
    let dp = 0.5 * k * (phi / theta1 + (l0 + l1) * log1p_over_x_prime(x) / theta0) / theta0;
    (p, dp)
}

impl Law {
    /// The strain energy density `W(C)` (per reference volume); `None` if `det C <= 0`.
    pub fn energy(&self, c: &Tensor) -> Option<f64> {
        let (l, m) = (self.lambda, self.mu);
        match self.model {
            Model::Linear | Model::SaintVenantKirchhoff => {
                let e = lin(0.5, c, -0.5, &identity());
                let tr = trace(&e);
                Some(0.5 * l * tr * tr + m * ddot(&e, &e))
            }
            Model::NeoHookean => {
                let i3 = det(c);
                if i3.is_nan() || i3 <= 0.0 {
                    return None;
                }
                let ln_j = 0.5 * i3.ln();
                Some(0.5 * m * (trace(c) - 3.0) - m * ln_j + 0.5 * l * ln_j * ln_j)
            }
        }
    }

    /// The second Piola-Kirchhoff stress `S = 2 dW/dC`.
    /// Saint Venant-Kirchhoff: `S = lambda tr(E) I + 2 mu E`; neo-Hooke:
    /// `S = mu (I - C^-1) + lambda ln J C^-1`.
    pub fn stress(&self, c: &Tensor) -> Tensor {
        let (l, m) = (self.lambda, self.mu);
        match self.model {
            Model::Linear | Model::SaintVenantKirchhoff => {
                let e = lin(0.5, c, -0.5, &identity());
                lin(l * trace(&e), &identity(), 2.0 * m, &e)
            }
            Model::NeoHookean => {
                let i3 = det(c);
                let ci = lin(1.0 / i3, &cofactor(c), 0.0, c);
                let ln_j = 0.5 * i3.ln();
                lin(m, &identity(), l * ln_j - m, &ci)
            }
        }
    }

    /// The algorithmic stress of the midpoint step between `c0` and `c1`, with
    /// `1/2 S_alg : (C_1 - C_0) = W(C_1) - W(C_0)` (see the module doc).
    pub fn midpoint_stress(&self, c0: &Tensor, c1: &Tensor) -> Tensor {
        let (l, m) = (self.lambda, self.mu);
        match self.model {
            Model::Linear | Model::SaintVenantKirchhoff => {
                let ca = lin(0.5, c0, 0.5, c1);
                self.stress(&ca)
            }
            Model::NeoHookean => {
                let nh = NeoHookeStep::new(l, m, c0, c1);
                lin(m, &identity(), 2.0 * nh.g, &nh.d3)
            }
        }
    }

    /// `dS_alg/dC_1 : sym(e_r (x) e_s)` for each Voigt pair `(r, s)` of `voigt` into `out`.
    fn midpoint_stress_derivatives<const V: usize>(
        &self,
        c0: &Tensor,
        c1: &Tensor,
        nh: Option<&NeoHookeStep>,
        voigt: &[(usize, usize)],
        out: &mut [Tensor; V],
    ) {
        let (l, m) = (self.lambda, self.mu);
        match (self.model, nh) {
            (Model::NeoHookean, Some(nh)) => {
                // dS = 2 (dg/dI_3,1) (cof C_1 : delta) D_3 + 2 g dD_3 : delta,
                // dD_3 : delta = B(C_0 + 2 C_1, delta)/6, B the polar form of cof.
                let a = lin(1.0, c0, 2.0, c1);
                for (v, &(r, s)) in voigt.iter().enumerate() {
                    // cof C_1 : sym(e_r (x) e_s) = (cof C_1)_rs (cof C_1 is symmetric).
                    let x = 2.0 * nh.dg_di1 * nh.cof1[r][s];
                    let b = cof_polar_unit(&a, r, s);
                    out[v] = lin(x, &nh.d3, nh.g / 3.0, &b);
                }
            }
            _ => {
                // S_alg = CC : (E_0 + E_1)/2, dE_1 = delta/2: dS = CC : delta / 4.
                for (v, &(r, s)) in voigt.iter().enumerate() {
                    let mut d = [[0.0; 3]; 3];
                    if r == s {
                        d[r][r] = 0.5 * m;
                        for i in 0..3 {
                            d[i][i] += 0.25 * l;
                        }
                    } else {
                        d[r][s] = 0.25 * m;
                        d[s][r] = 0.25 * m;
                    }
                    out[v] = d;
                }
            }
        }
    }
}

/// `B(A, sym(e_r (x) e_s))`, the polar form of the cofactor with a unit symmetric tensor:
/// `B(A, D)_ij = eps_ikl eps_jmn A_km D_ln`.
fn cof_polar_unit(a: &Tensor, r: usize, s: usize) -> Tensor {
    // For D = e_r (x) e_s: B_ij = eps_ikr eps_jms A_km (one term each: k and m are the
    // indices other than i, r and j, s); symmetrized over (r, s).
    let one = |r: usize, s: usize| -> Tensor {
        let mut b = [[0.0; 3]; 3];
        for i in (0..3).filter(|&i| i != r) {
            let (k, ek) = (3 - i - r, if (r + 3 - i) % 3 == 2 { 1.0 } else { -1.0 });
            for j in (0..3).filter(|&j| j != s) {
                let (m, em) = (3 - j - s, if (s + 3 - j) % 3 == 2 { 1.0 } else { -1.0 });
                b[i][j] = ek * em * a[k][m];
            }
        }
        b
    };
    if r == s {
        one(r, r)
    } else {
        lin(0.5, &one(r, s), 0.5, &one(s, r))
    }
}

/// The neo-Hooke step quantities at one point: `g`, `dg/dI_3,1`, `D_3`, `cof C_1`.
struct NeoHookeStep {
    g: f64,
    /// `dg/dI_3,1` and `cof C_1` (for the tangent only; zero without it).
    dg_di1: f64,
    d3: Tensor,
    cof1: Tensor,
    /// `ln I_3` of both states (the energies reuse them).
    l0: f64,
    l1: f64,
}

impl NeoHookeStep {
    fn new(l: f64, m: f64, c0: &Tensor, c1: &Tensor) -> NeoHookeStep {
        NeoHookeStep::with_invariants(l, m, c0, c1, det(c0), det(c1), true)
    }

    /// With `I_3 = det C` of both states given (the kernel has them as `(det F)^2`), and the
    /// tangent's parts only when `tangent`.
    fn with_invariants(
        l: f64,
        m: f64,
        c0: &Tensor,
        c1: &Tensor,
        i0: f64,
        i1: f64,
        tangent: bool,
    ) -> NeoHookeStep {
        let x = (i1 - i0) / i0;
        let (l0, l1) = (i0.ln(), i1.ln());
        let h = -0.5 * m + 0.125 * l * (l0 + l1);
        let phi = log1p_over_x(x);
        let g = phi * h / i0;
        let ca = lin(0.5, c0, 0.5, c1);
        let (cof0, cofa, cof1) = (cofactor(c0), cofactor(&ca), cofactor(c1));
        let mut d3 = [[0.0; 3]; 3];
        for i in 0..3 {
            for j in 0..3 {
                d3[i][j] = (cof0[i][j] + 4.0 * cofa[i][j] + cof1[i][j]) / 6.0;
            }
        }
        let dg_di1 = match tangent {
            true => (log1p_over_x_prime(x) * h / i0 + phi * 0.125 * l / i1) / i0,
            false => 0.0,
        };
        NeoHookeStep { g, dg_di1, d3, cof1, l0, l1 }
    }

    /// `W = mu/2 (tr C - 3) - mu/2 ln I_3 + lambda/8 (ln I_3)^2` of one state.
    fn energy(l: f64, m: f64, c: &Tensor, ln_i3: f64) -> f64 {
        0.5 * m * (trace(c) - 3.0) - 0.5 * m * ln_i3 + 0.125 * l * ln_i3 * ln_i3
    }
}

// ---------------------------------------------------------------------------------------------
// Element kernels.

/// Voigt pairs `(p, q)`: 2D xx, yy, xy; 3D xx, yy, zz, yz, xz, xy.
const VOIGT2: [(usize, usize); 3] = [(0, 0), (1, 1), (0, 1)];
const VOIGT3: [(usize, usize); 6] = [(0, 0), (1, 1), (2, 2), (1, 2), (0, 2), (0, 1)];

/// The deformation gradient `F = I + sum_a u_a (x) G_a` (`F_33 = 1` in 2D).
#[inline(always)]
fn deformation_gradient<const N: usize, const D: usize>(g: &[[f64; 3]; N], u: &[f64]) -> Tensor {
    let mut f = identity();
    for a in 0..N {
        for i in 0..D {
            let ui = u[a * D + i];
            for j in 0..D {
                f[i][j] += ui * g[a][j];
            }
        }
    }
    f
}

/// What an element evaluation yields: the algorithmic force (and, if asked, its tangent with
/// respect to `u_1`), and the strain energies at both states.
pub struct ElementStep {
    pub w0: f64,
    pub w1: f64,
}

/// The midpoint internal force of a cell between the nodal displacements `u0` and `u1`
/// (interlaced, `n d` long): `force[a d + i] = sum_q w_q det J_q (F_m S_alg G_a)_i`, and with
/// `tangent` its derivative `d force / d u1` (row-major `(n d)^2`). Both overwritten. Returns
/// the strain energies `int W(C_0)` and `int W(C_1)` of the cell. `Err` if `det F <= 0` at a
/// quadrature point of either state (or the reference cell is inverted: `state` 0, det 0).
pub fn midpoint_force(
    kind: ElementKind,
    coords: &[[f64; 3]],
    law: &Law,
    u0: &[f64],
    u1: &[f64],
    force: &mut [f64],
    tangent: Option<&mut [f64]>,
) -> Result<ElementStep, Inverted> {
    dispatch(kind, coords, law, u0, u1, force, tangent, None)
}

/// The volumetric part of a neo-Hookean simplex whose pressure is the averaged nodal one
/// (`formulation = "mixed"` on triangles and tetrahedra; `assembly::nodal_pressure`): the
/// stored energy `sum_a L_a/2 (ln theta_a)^2`, `theta_a = v_a / V_a` with the nodal volumes
/// `v_a = sum_{K ∋ a} |K_0| J_K / (d + 1)`, is the nodes', not the cell's. Its discrete
/// gradient `p_a = (U_a(v_1) - U_a(v_0)) / (v_1 - v_0)` comes in as the cell's mean
/// `p_K = sum_{a ∈ K} p_a / (d + 1)`, and the cell adds `S_vol = kappa D_3`,
/// `kappa = 2 p_K / (J_0 + J_1)`: `1/2 S_vol : dC = p_K (J_1 - J_0)` per unit reference volume,
/// so that `sum_K |K_0| p_K (J_1 - J_0) = sum_a p_a (v_1 - v_0) = sum_a U_a(v_1) - U_a(v_0)`
/// (exact energy; `S_alg` stays symmetric, so momentum and angular momentum are kept).
pub struct NodalPressure<'a> {
    /// `p_K`, the mean algorithmic pressure of the cell's nodes.
    pub pressure: f64,
    /// With the tangent: `d force / d p_K` (`n d` long, overwritten) ...
    pub dforce: &'a mut [f64],
    /// ... and `d (|K_0| J_1) / d u_1` (`n d` long, overwritten): where the nodal volumes
    /// move, `d v_1,a / d u_1 = sum_{K ∋ a} dvolume_K / (d + 1)`.
    pub dvolume: &'a mut [f64],
}

/// [`midpoint_force`] of a simplex with the averaged nodal pressure ([`NodalPressure`]): the
/// point-wise law without `lambda`, plus `p_K`'s share. Energies without the nodal part.
#[allow(clippy::too_many_arguments)] // midpoint_force's arguments and the nodal pressure
pub fn midpoint_force_nodal(
    kind: ElementKind,
    coords: &[[f64; 3]],
    law: &Law,
    u0: &[f64],
    u1: &[f64],
    nodal: NodalPressure,
    force: &mut [f64],
    tangent: Option<&mut [f64]>,
) -> Result<ElementStep, Inverted> {
    assert!(
        kind.is_simplex() && law.model == Model::NeoHookean,
        "nodal pressure: neo-Hookean simplices"
    );
    dispatch(kind, coords, law, u0, u1, force, tangent, Some(nodal))
}

/// `|K_0|` and `J` of both states of a simplex (one point: `F` is constant).
pub fn simplex_jacobians(
    kind: ElementKind,
    coords: &[[f64; 3]],
    u0: &[f64],
    u1: &[f64],
) -> Result<(f64, f64, f64), Inverted> {
    fn one<const N: usize, const D: usize>(
        kind: ElementKind,
        coords: &[[f64; 3]],
        u0: &[f64],
        u1: &[f64],
    ) -> Result<(f64, f64, f64), Inverted> {
        let t = table(kind, stiffness_order(kind));
        debug_assert_eq!(t.w.len(), 1, "one point on simplices");
        let p = QuadraturePoint::<N>::new::<D>(t, 0, coords, u0, u1)?;
        Ok((p.w, p.j0, p.j1))
    }
    match kind {
        ElementKind::Tri3 => one::<3, 2>(kind, coords, u0, u1),
        ElementKind::Tet4 => one::<4, 3>(kind, coords, u0, u1),
        _ => panic!("simplex_jacobians of {}: not a simplex", kind.name()),
    }
}

#[allow(clippy::too_many_arguments)]
fn dispatch(
    kind: ElementKind,
    coords: &[[f64; 3]],
    law: &Law,
    u0: &[f64],
    u1: &[f64],
    force: &mut [f64],
    tangent: Option<&mut [f64]>,
    nodal: Option<NodalPressure>,
) -> Result<ElementStep, Inverted> {
    let (c, l, a, b) = (coords, law, u0, u1);
    match kind {
        ElementKind::Tri3 => midpoint_impl::<3, 2, 3>(kind, c, l, a, b, force, tangent, nodal),
        ElementKind::Quad4 => midpoint_impl::<4, 2, 3>(kind, c, l, a, b, force, tangent, nodal),
        ElementKind::Tet4 => midpoint_impl::<4, 3, 6>(kind, c, l, a, b, force, tangent, nodal),
        ElementKind::Hex8 => midpoint_impl::<8, 3, 6>(kind, c, l, a, b, force, tangent, nodal),
        ElementKind::Point1 | ElementKind::Line2 => {
            panic!("hyperelastic kernels for {}: not a cell of a 2D or 3D mesh", kind.name())
        }
    }
}

/// One quadrature point of a cell between two states: the physical gradients `G_a`, the
/// weight `w_q det J_q`, and `F` and `J = det F` of both states.
struct QuadraturePoint<const N: usize> {
    g: [[f64; 3]; N],
    w: f64,
    f0: Tensor,
    f1: Tensor,
    j0: f64,
    j1: f64,
}

impl<const N: usize> QuadraturePoint<N> {
    /// `Err` if the reference cell or either state is inverted there.
    #[inline(always)]
    fn new<const D: usize>(
        t: &super::kernels::Table,
        q: usize,
        coords: &[[f64; 3]],
        u0: &[f64],
        u1: &[f64],
    ) -> Result<Self, Inverted> {
        let mut g = [[0.0f64; 3]; N];
        g.copy_from_slice(&t.dn[q][..N]);
        let det_j = map_gradients(D, N, coords, &mut g);
        if det_j.is_nan() || det_j <= 0.0 {
            return Err(Inverted { det_f: 0.0, state: 0 });
        }
        let f0 = deformation_gradient::<N, D>(&g, u0);
        let f1 = deformation_gradient::<N, D>(&g, u1);
        let (j0, j1) = (det(&f0), det(&f1));
        for (state, j) in [(0, j0), (1, j1)] {
            if j.is_nan() || j <= 0.0 {
                return Err(Inverted { det_f: j, state });
            }
        }
        Ok(QuadraturePoint { g, w: t.w[q] * det_j, f0, f1, j0, j1 })
    }
}

#[inline(always)]
#[allow(clippy::too_many_arguments)]
fn midpoint_impl<const N: usize, const D: usize, const V: usize>(
    kind: ElementKind,
    coords: &[[f64; 3]],
    law: &Law,
    u0: &[f64],
    u1: &[f64],
    force: &mut [f64],
    mut tangent: Option<&mut [f64]>,
    mut nodal: Option<NodalPressure>,
) -> Result<ElementStep, Inverted> {
    let nd = N * D;
    check_len("hyperelastic coords", kind, coords.len(), N);
    check_len("hyperelastic u0", kind, u0.len(), nd);
    check_len("hyperelastic u1", kind, u1.len(), nd);
    check_len("hyperelastic force", kind, force.len(), nd);
    let voigt: &[(usize, usize)] = if D == 2 { &VOIGT2 } else { &VOIGT3 };
    let force = &mut force[..nd];
    force.fill(0.0);
    if let Some(k) = tangent.as_deref_mut() {
        check_len("hyperelastic tangent", kind, k.len(), nd * nd);
        k[..nd * nd].fill(0.0);
    }
    let t = table(kind, stiffness_order(kind));
    let (mut w0, mut w1) = (0.0, 0.0);
    // Mean dilatation: the cell's volume and mean Jacobians of both states, the volumetric
    // `V'_alg / |K|` and its derivative in theta_1; the point-wise law without lambda.
    let mean = law.mean_dilatation && law.model == Model::NeoHookean && t.w.len() > 1;
    let point_law = if mean || nodal.is_some() { Law { lambda: 0.0, ..*law } } else { *law };
    if let (Some(np), true) = (nodal.as_mut(), tangent.is_some()) {
        np.dforce[..nd].fill(0.0);
        np.dvolume[..nd].fill(0.0);
    }
    let (mut volume, mut th0, mut th1) = (0.0, 0.0, 0.0);
    if mean {
        for q in 0..t.w.len() {
            let p = QuadraturePoint::<N>::new::<D>(t, q, coords, u0, u1)?;
            let (w, j0, j1) = (p.w, p.j0, p.j1);
            volume += w;
            th0 += w * j0;
            th1 += w * j1;
        }
        th0 /= volume;
        th1 /= volume;
    }
    let (lt0, lt1) = (th0.ln(), th1.ln());
    let xt = if mean { (th1 - th0) / th0 } else { 0.0 };
    let vp = 0.5 * law.lambda * (lt0 + lt1) * log1p_over_x(xt) / th0;
    let dvp =
        0.5 * law.lambda * (log1p_over_x(xt) / th1 + (lt0 + lt1) * log1p_over_x_prime(xt) / th0)
            / th0;
    if mean {
        w0 += volume * 0.5 * law.lambda * lt0 * lt0;
        w1 += volume * 0.5 * law.lambda * lt1 * lt1;
    }
    // The rank-one part of the tangent: rows `A_a,i`, columns `B_b,k`.
    let mut rank_a = [0.0f64; MAX_DOFS];
    let mut rank_b = [0.0f64; MAX_DOFS];
    for q in 0..t.w.len() {
        let QuadraturePoint { g, w, f0, f1, j0, j1 } =
            QuadraturePoint::<N>::new::<D>(t, q, coords, u0, u1)?;
        let (c0, c1) = (right_cauchy_green(&f0), right_cauchy_green(&f1));
        let fm = lin(0.5, &f0, 0.5, &f1);
        // Neo-Hooke with I_3 = J^2 (det C = (det F)^2) and its energies from the step's logs.
        let nh = (law.model == Model::NeoHookean).then(|| {
            let (l, m) = (point_law.lambda, law.mu);
            let t = tangent.is_some();
            let mut nh = NeoHookeStep::with_invariants(l, m, &c0, &c1, j0 * j0, j1 * j1, t);
            // The cell's pressure per unit volume: its own (mean dilatation) or its nodes'.
            let own = match &nodal {
                Some(np) => Some(np.pressure),
                None => mean.then_some(vp),
            };
            if let Some(p) = own {
                // kappa_q/2 joins g; its local derivative through J_1,q (dJ/dI_3 = 1/(2 J)).
                let kappa = 2.0 * p / (j0 + j1);
                nh.g += 0.5 * kappa;
                nh.dg_di1 -= 0.5 * kappa / (j0 + j1) / (2.0 * j1);
            }
            nh
        });
        match &nh {
            Some(nh) => {
                w0 += w * NeoHookeStep::energy(point_law.lambda, law.mu, &c0, nh.l0);
                w1 += w * NeoHookeStep::energy(point_law.lambda, law.mu, &c1, nh.l1);
            }
            None => {
                let bad = |state| Inverted { det_f: f64::NAN, state };
                w0 += w * law.energy(&c0).ok_or(bad(0))?;
                w1 += w * law.energy(&c1).ok_or(bad(1))?;
            }
        }
        let s = match &nh {
            Some(nh) => lin(law.mu, &identity(), 2.0 * nh.g, &nh.d3),
            None => law.midpoint_stress(&c0, &c1),
        };
        // P = F_m S_alg; f_a += w P G_a.
        let mut p = [[0.0f64; 3]; 3];
        for i in 0..D {
            for jj in 0..D {
                let mut v = 0.0;
                for k in 0..D {
                    v += fm[i][k] * s[k][jj];
                }
                p[i][jj] = w * v;
            }
        }
        for a in 0..N {
            for i in 0..D {
                let mut v = 0.0;
                for jj in 0..D {
                    v += p[i][jj] * g[a][jj];
                }
                force[a * D + i] += v;
            }
        }
        let Some(k) = tangent.as_deref_mut() else { continue };
        if let (true, Some(nh)) = (mean || nodal.is_some(), &nh) {
            // d f_a = w F_m D_3 G_a d kappa_q, d kappa_q = 2/(J_0 + J_1) d p, with the cell's
            // d p = dvp d theta_1, d theta_1 / d u_1,b = sum_p w_p/|K| cof(F_1,p) G_b,p, or
            // the nodes' pressure (d p and d v_1 handed out).
            let scale = w * 2.0 / (j0 + j1);
            let cof1 = cofactor(&f1);
            for a in 0..N {
                for i in 0..D {
                    let mut v = 0.0;
                    for p_ in 0..D {
                        for jj in 0..D {
                            v += fm[i][p_] * nh.d3[p_][jj] * g[a][jj];
                        }
                    }
                    let mut c = 0.0;
                    for jj in 0..D {
                        c += cof1[i][jj] * g[a][jj];
                    }
                    match nodal.as_mut() {
                        Some(np) => {
                            np.dforce[a * D + i] += scale * v;
                            np.dvolume[a * D + i] += w * c;
                        }
                        None => {
                            rank_a[a * D + i] += scale * dvp * v;
                            rank_b[a * D + i] += w / volume * c;
                        }
                    }
                }
            }
        }
        // dS_alg/dC_1 : sym(e_r (x) e_s) for each Voigt pair (r, s): CC_pjrs = dds[v][p][j].
        let mut dds = [[[0.0f64; 3]; 3]; V];
        point_law.midpoint_stress_derivatives(&c0, &c1, nh.as_ref(), voigt, &mut dds);
        // The point's tangent as one 4-index array, then contracted with the gradients:
        //   K_ab,ik += sum_js G_a,j A[i][j][k][s] G_b,s,
        //   A[i][j][k][s] = w (2 sum_pr Fm_ip CC_pjrs F1_kr + 1/2 delta_ik S_js)
        // (dC_1 = F_1^T (e_k (x) G_b) + its transpose and CC symmetric in r, s give the 2).
        let mut aa = [[[[0.0f64; D]; D]; D]; D];
        for (v, &(r, s_)) in voigt.iter().enumerate() {
            // Q = 2 w Fm CC_(rs) (D x D).
            let mut q = [[0.0f64; D]; D];
            for i in 0..D {
                for j in 0..D {
                    let mut x = 0.0;
                    for p_ in 0..D {
                        x += fm[i][p_] * dds[v][p_][j];
                    }
                    q[i][j] = 2.0 * w * x;
                }
            }
            for i in 0..D {
                for j in 0..D {
                    for kk in 0..D {
                        aa[i][j][kk][s_] += q[i][j] * f1[kk][r];
                        if r != s_ {
                            aa[i][j][kk][r] += q[i][j] * f1[kk][s_];
                        }
                    }
                }
            }
        }
        for i in 0..D {
            for j in 0..D {
                for s_ in 0..D {
                    aa[i][j][i][s_] += 0.5 * w * s[j][s_];
                }
            }
        }
        // H_b[i][j][k] = sum_s A[i][j][k][s] G_b,s.
        let mut h = [[[[0.0f64; D]; D]; D]; N];
        for b in 0..N {
            for i in 0..D {
                for j in 0..D {
                    for kk in 0..D {
                        let mut x = 0.0;
                        for s_ in 0..D {
                            x += aa[i][j][kk][s_] * g[b][s_];
                        }
                        h[b][i][j][kk] = x;
                    }
                }
            }
        }
        for a in 0..N {
            for i in 0..D {
                let row = &mut k[(a * D + i) * nd..(a * D + i + 1) * nd];
                for b in 0..N {
                    for kk in 0..D {
                        let mut x = 0.0;
                        for j in 0..D {
                            x += g[a][j] * h[b][i][j][kk];
                        }
                        row[b * D + kk] += x;
                    }
                }
            }
        }
    }
    if let (true, Some(k)) = (mean, tangent) {
        for r in 0..nd {
            for c in 0..nd {
                k[r * nd + c] += rank_a[r] * rank_b[c];
            }
        }
    }
    Ok(ElementStep { w0, w1 })
}

/// The strain energy `int_K W(C(u)) dV` of a cell (`Err` if it is inverted).
pub fn strain_energy(
    kind: ElementKind,
    coords: &[[f64; 3]],
    law: &Law,
    u: &[f64],
) -> Result<f64, Inverted> {
    let mut f = [0.0; MAX_DOFS];
    let n = kind.n_nodes() * kind.dim();
    midpoint_force(kind, coords, law, u, u, &mut f[..n], None).map(|e| e.w1)
}

/// The size of each node's internal force under a unit strain, `out[a] = modulus sum_q w_q
/// det J_q |G_a(x_q)|` (`modulus` e.g. `lambda + 2 mu`): the scale below which a computed
/// internal force is round-off (its stresses cancel to about `eps modulus`).
pub fn unit_strain_force(kind: ElementKind, coords: &[[f64; 3]], modulus: f64, out: &mut [f64]) {
    let n = kind.n_nodes();
    let d = kind.dim();
    let t = table(kind, stiffness_order(kind));
    out[..n].fill(0.0);
    for q in 0..t.w.len() {
        let mut g = t.dn[q];
        let det_j = map_gradients(d, n, coords, &mut g[..n]);
        for a in 0..n {
            let norm = (g[a][0] * g[a][0] + g[a][1] * g[a][1] + g[a][2] * g[a][2]).sqrt();
            out[a] += modulus * t.w[q] * det_j.abs() * norm;
        }
    }
}

/// The deformation gradient of a cell at the reference point `xi` (3 x 3, `F_33 = 1` in 2D).
pub fn deformation_gradient_at(
    kind: ElementKind,
    coords: &[[f64; 3]],
    u: &[f64],
    xi: [f64; 3],
) -> Tensor {
    let mut g = [[0.0f64; 3]; super::kernels::MAX_NODES];
    let n = kind.n_nodes();
    let d = kind.dim();
    super::shape::physical_gradients(kind, coords, xi, &mut g[..n]);
    let mut f = identity();
    for a in 0..n {
        for i in 0..d {
            for j in 0..d {
                f[i][j] += u[a * d + i] * g[a][j];
            }
        }
    }
    f
}

/// The Cauchy stress `sigma = F S F^T / J` of a law at a deformation gradient (`J > 0`).
pub fn cauchy_stress(law: &Law, f: &Tensor) -> Tensor {
    let c = right_cauchy_green(f);
    let s = law.stress(&c);
    let j = det(f);
    let mut fs = [[0.0; 3]; 3];
    for i in 0..3 {
        for k in 0..3 {
            for l in 0..3 {
                fs[i][k] += f[i][l] * s[l][k];
            }
        }
    }
    let mut sigma = [[0.0; 3]; 3];
    for i in 0..3 {
        for jj in 0..3 {
            for k in 0..3 {
                sigma[i][jj] += fs[i][k] * f[jj][k] / j;
            }
        }
    }
    sigma
}

/// The rotation `R` of the polar decomposition `F = R U` (`det F > 0`), by Higham's
/// iteration `R <- (R + R^-T)/2` from `R = F`, which converges quadratically.
pub fn rotation(f: &Tensor) -> Tensor {
    let mut r = *f;
    for _ in 0..60 {
        let d = det(&r);
        if d.is_nan() || d <= 0.0 {
            break;
        }
        // R^-T = cof(R)/det R.
        let c = cofactor(&r);
        let mut next = [[0.0; 3]; 3];
        let mut change = 0.0f64;
        for i in 0..3 {
            for j in 0..3 {
                next[i][j] = 0.5 * (r[i][j] + c[i][j] / d);
                change = change.max((next[i][j] - r[i][j]).abs());
            }
        }
        r = next;
        if change < 1e-15 {
            break;
        }
    }
    r
}

/// The angle of a rotation matrix in degrees, `acos((tr R - 1)/2)` (in 2D with `R_33 = 1`).
pub fn rotation_angle_degrees(r: &Tensor) -> f64 {
    ((trace(r) - 1.0) / 2.0).clamp(-1.0, 1.0).acos().to_degrees()
}

#[cfg(test)]
#[path = "hyperelastic_tests.rs"]
mod tests;
