//! Quadrature rules on the reference elements (gmsh ordering, see [`ElementKind`]).
//!
//! Reference domains and the rules returned by [`gauss`] for a requested polynomial `order`
//! (total degree that is integrated exactly):
//!
//! | kind     | reference domain            | rule                                                   |
//! |----------|-----------------------------|--------------------------------------------------------|
//! | `Point1` | the point 0                 | 1 point, weight 1                                      |
//! | `Line2`  | [-1, 1]                     | Gauss-Legendre, `q = order/2 + 1 = ceil((order+1)/2)` points |
//! | `Quad4`  | [-1, 1]^2                   | tensor Gauss-Legendre, `q x q` points                  |
//! | `Hex8`   | [-1, 1]^3                   | tensor Gauss-Legendre, `q x q x q` points              |
//! | `Tri3`   | (0,0),(1,0),(0,1), area 1/2 | order 0-1: centroid (1 pt); 2: 3 pt (edge-interior points 1/6, 2/3); 3-4: Strang-Fix/Dunavant 6 pt (degree 4); 5: Radon/Dunavant 7 pt (degree 5); >= 6: collapsed (Duffy) Gauss-Legendre product rule |
//! | `Tet4`   | unit tetrahedron, vol 1/6   | order 0-1: centroid (1 pt); 2: 4 pt (degree 2); 3-5: Walkington/Keast 14 pt (degree 5); >= 6: collapsed (Duffy) Gauss-Legendre product rule |
//!
//! All weights are positive (the negative-weight Dunavant 4-point and Keast 5/11-point rules are
//! deliberately not used). Weights sum to the reference measure (2, 4, 8, 1/2, 1/6; 1 for a
//! point). Unused coordinates of a point are 0.

#![allow(clippy::needless_range_loop)] // index-heavy small dense linear algebra

use super::element::ElementKind;

/// Gauss-Legendre points and weights on [-1, 1] with `n >= 1` points (exact for degree
/// `2n - 1`). Computed by Newton iteration on the Legendre recurrence (accurate to rounding).
pub fn gauss_legendre(n: usize) -> Vec<(f64, f64)> {
    assert!(n >= 1, "gauss_legendre: need at least one point");
    // Closed forms for n <= 5 (correctly rounded up to an ulp), Newton beyond.
    let half: Vec<(f64, f64)> = match n {
        1 => vec![(0.0, 2.0)],
        2 => vec![(1.0 / 3f64.sqrt(), 1.0)],
        3 => vec![(0.0, 8.0 / 9.0), ((3.0f64 / 5.0).sqrt(), 5.0 / 9.0)],
        4 => {
            let r = 2.0 / 7.0 * (6.0f64 / 5.0).sqrt();
            let s30 = 30f64.sqrt();
            vec![
                ((3.0 / 7.0 - r).sqrt(), (18.0 + s30) / 36.0),
                ((3.0 / 7.0 + r).sqrt(), (18.0 - s30) / 36.0),
            ]
        }
        5 => {
            let r = 2.0 * (10.0f64 / 7.0).sqrt();
            let s70 = 70f64.sqrt();
            vec![
                (0.0, 128.0 / 225.0),
                ((5.0 - r).sqrt() / 3.0, (322.0 + 13.0 * s70) / 900.0),
                ((5.0 + r).sqrt() / 3.0, (322.0 - 13.0 * s70) / 900.0),
            ]
        }
        _ => {
            // Non-negative roots by Newton from Tricomi's initial guesses.
            let mut v = Vec::new();
            for i in 0..n.div_ceil(2) {
                let mut x = (std::f64::consts::PI * (i as f64 + 0.75) / (n as f64 + 0.5)).cos();
                for _ in 0..100 {
                    let (p, _, d) = legendre(n, x);
                    let dx = p / d;
                    x -= dx;
                    if dx.abs() <= 1e-17 {
                        break;
                    }
                }
                if n % 2 == 1 && i == n / 2 {
                    x = 0.0;
                }
                let (_, pm1, _) = legendre(n, x);
                let w = 2.0 * (1.0 - x * x) / (n as f64 * pm1).powi(2);
                v.push((x, w));
            }
            v.reverse();
            v
        }
    };
    // Assemble the symmetric rule in increasing order from the non-negative half
    // (`half` is sorted by increasing x >= 0).
    let mut out = Vec::with_capacity(n);
    for &(x, w) in half.iter().rev() {
        if x > 0.0 {
            out.push((-x, w));
        }
    }
    for &(x, w) in half.iter() {
        out.push((x, w));
    }
    debug_assert_eq!(out.len(), n);
    out
}

/// Legendre polynomials P_n(x), P_{n-1}(x) and the derivative P_n'(x) (n >= 1, |x| < 1).
fn legendre(n: usize, x: f64) -> (f64, f64, f64) {
    let mut p0 = 1.0;
    let mut p1 = x;
    for k in 2..=n {
        let kf = k as f64;
        let p2 = ((2.0 * kf - 1.0) * x * p1 - (kf - 1.0) * p0) / kf;
        p0 = p1;
        p1 = p2;
    }
    let d = n as f64 * (x * p1 - p0) / (x * x - 1.0);
    (p1, p0, d)
}

/// Number of Gauss-Legendre points per direction used by the tensor rules for `order`:
/// `ceil((order + 1) / 2)`.
pub fn points_per_direction(order: usize) -> usize {
    order / 2 + 1
}

/// Quadrature points (reference coordinates, padded with zeros to 3) and weights on the
/// reference element of `kind`, exact for polynomials of total degree `order` (for the tensor
/// kinds: of degree `order` in each variable). See the module documentation for the rules.
pub fn gauss(kind: ElementKind, order: usize) -> Vec<([f64; 3], f64)> {
    match kind {
        ElementKind::Point1 => vec![([0.0; 3], 1.0)],
        ElementKind::Line2 => gauss_legendre(points_per_direction(order))
            .into_iter()
            .map(|(x, w)| ([x, 0.0, 0.0], w))
            .collect(),
        ElementKind::Quad4 => {
            let g = gauss_legendre(points_per_direction(order));
            let mut v = Vec::with_capacity(g.len() * g.len());
            for &(y, wy) in &g {
                for &(x, wx) in &g {
                    v.push(([x, y, 0.0], wx * wy));
                }
            }
            v
        }
        ElementKind::Hex8 => {
            let g = gauss_legendre(points_per_direction(order));
            let mut v = Vec::with_capacity(g.len().pow(3));
            for &(z, wz) in &g {
                for &(y, wy) in &g {
                    for &(x, wx) in &g {
                        v.push(([x, y, z], wx * wy * wz));
                    }
                }
            }
            v
        }
        ElementKind::Tri3 => triangle(order),
        ElementKind::Tet4 => tetrahedron(order),
    }
}

/// Fully symmetric triangle orbit of the barycentric point (a, a, 1-2a), weight `w` each.
fn tri_orbit3(v: &mut Vec<([f64; 3], f64)>, a: f64, w: f64) {
    let b = 1.0 - 2.0 * a;
    v.push(([a, a, 0.0], w));
    v.push(([b, a, 0.0], w));
    v.push(([a, b, 0.0], w));
}

fn triangle(order: usize) -> Vec<([f64; 3], f64)> {
    let mut v = Vec::new();
    match order {
        0 | 1 => v.push(([1.0 / 3.0, 1.0 / 3.0, 0.0], 0.5)),
        2 => tri_orbit3(&mut v, 1.0 / 6.0, 1.0 / 6.0),
        3 | 4 => {
            // Strang-Fix / Dunavant degree 4, 6 points (weights for area 1 halved).
            tri_orbit3(&mut v, 0.445_948_490_915_964_9, 0.5 * 0.223_381_589_678_011_47);
            tri_orbit3(&mut v, 0.091_576_213_509_770_74, 0.5 * 0.109_951_743_655_321_87);
        }
        5 => {
            // Radon / Dunavant degree 5, 7 points, closed form with sqrt(15).
            let s = 15f64.sqrt();
            v.push(([1.0 / 3.0, 1.0 / 3.0, 0.0], 0.5 * 9.0 / 40.0));
            tri_orbit3(&mut v, (6.0 - s) / 21.0, 0.5 * (155.0 - s) / 1200.0);
            tri_orbit3(&mut v, (6.0 + s) / 21.0, 0.5 * (155.0 + s) / 1200.0);
        }
        _ => {
            // Collapsed product rule: x = u, y = (1-u) v on [0,1]^2, Jacobian (1-u).
            // Degree order+1 in u, order in v.
            let gu = gauss_legendre(order.div_ceil(2) + 1);
            let gv = gauss_legendre(order / 2 + 1);
            for &(su, wu) in &gu {
                let u = 0.5 * (su + 1.0);
                for &(sv, wv) in &gv {
                    let t = 0.5 * (sv + 1.0);
                    v.push(([u, (1.0 - u) * t, 0.0], 0.25 * wu * wv * (1.0 - u)));
                }
            }
        }
    }
    v
}

fn tetrahedron(order: usize) -> Vec<([f64; 3], f64)> {
    let mut v = Vec::new();
    match order {
        0 | 1 => v.push(([0.25; 3], 1.0 / 6.0)),
        2 => {
            let a = (5.0 - 5f64.sqrt()) / 20.0;
            let b = 1.0 - 3.0 * a;
            let w = 1.0 / 24.0;
            v.push(([a, a, a], w));
            v.push(([b, a, a], w));
            v.push(([a, b, a], w));
            v.push(([a, a, b], w));
        }
        3..=5 => {
            // Walkington (also Keast #6 family) degree 5, 14 points, positive weights.
            for &(a, w) in &[
                (0.092_735_250_310_891_2, 0.012_248_840_519_393_66),
                (0.310_885_919_263_300_6, 0.018_781_320_953_002_64),
            ] {
                let b = 1.0 - 3.0 * a;
                v.push(([a, a, a], w));
                v.push(([b, a, a], w));
                v.push(([a, b, a], w));
                v.push(([a, a, b], w));
            }
            let c = 0.454_496_295_874_350_4;
            let d = 0.5 - c;
            let w = 0.007_091_003_462_846_911;
            // The 6 permutations of barycentric (c, c, d, d); reference coords = last three.
            for p in [[c, c, d], [c, d, c], [d, c, c], [d, d, c], [d, c, d], [c, d, d]] {
                v.push((p, w));
            }
        }
        _ => {
            // Collapsed product rule: x = u, y = (1-u) v, z = (1-u)(1-v) t on [0,1]^3,
            // Jacobian (1-u)^2 (1-v). Degrees: order+2 in u, order+1 in v, order in t.
            let gu = gauss_legendre((order + 2) / 2 + 1);
            let gv = gauss_legendre(order.div_ceil(2) + 1);
            let gt = gauss_legendre(order / 2 + 1);
            for &(su, wu) in &gu {
                let u = 0.5 * (su + 1.0);
                for &(sv, wv) in &gv {
                    let s = 0.5 * (sv + 1.0);
                    for &(st, wt) in &gt {
                        let t = 0.5 * (st + 1.0);
                        let x = [u, (1.0 - u) * s, (1.0 - u) * (1.0 - s) * t];
                        let w = 0.125 * wu * wv * wt * (1.0 - u) * (1.0 - u) * (1.0 - s);
                        v.push((x, w));
                    }
                }
            }
        }
    }
    v
}

#[cfg(test)]
mod tests {
    use super::*;

    fn fact(n: usize) -> f64 {
        (1..=n).map(|k| k as f64).product()
    }

    /// Exact integral of x^i y^j z^k on the reference element.
    fn exact_monomial(kind: ElementKind, e: [usize; 3]) -> f64 {
        let line = |p: usize| {
            if p % 2 == 1 {
                0.0
            } else {
                2.0 / (p as f64 + 1.0)
            }
        };
        match kind {
            ElementKind::Point1 => {
                if e == [0, 0, 0] {
                    1.0
                } else {
                    0.0
                }
            }
            ElementKind::Line2 => line(e[0]),
            ElementKind::Quad4 => line(e[0]) * line(e[1]),
            ElementKind::Hex8 => line(e[0]) * line(e[1]) * line(e[2]),
            ElementKind::Tri3 => fact(e[0]) * fact(e[1]) / fact(e[0] + e[1] + 2),
            ElementKind::Tet4 => {
                fact(e[0]) * fact(e[1]) * fact(e[2]) / fact(e[0] + e[1] + e[2] + 3)
            }
        }
    }

    fn integrate(rule: &[([f64; 3], f64)], e: [usize; 3]) -> f64 {
        rule.iter()
            .map(|(x, w)| {
                w * x[0].powi(e[0] as i32) * x[1].powi(e[1] as i32) * x[2].powi(e[2] as i32)
            })
            .sum()
    }

    /// Exponents of the monomials of total degree <= deg in `d` variables.
    fn monomials(d: usize, deg: usize) -> Vec<[usize; 3]> {
        let mut v = Vec::new();
        for i in 0..=deg {
            for j in 0..=(if d >= 2 { deg - i } else { 0 }) {
                for k in 0..=(if d >= 3 { deg - i - j } else { 0 }) {
                    v.push([i, j, k]);
                }
            }
        }
        v
    }

    /// Exact for all monomials of total degree <= order; returns the max error.
    fn max_err(kind: ElementKind, order: usize, deg: usize) -> f64 {
        let rule = gauss(kind, order);
        monomials(kind.dim(), deg)
            .into_iter()
            .map(|e| (integrate(&rule, e) - exact_monomial(kind, e)).abs())
            .fold(0.0, f64::max)
    }

    #[test]
    fn gauss_legendre_known_values() {
        let g = gauss_legendre(2);
        let x = 1.0 / 3f64.sqrt();
        assert!((g[0].0 + x).abs() < 1e-15 && (g[1].0 - x).abs() < 1e-15);
        assert!((g[0].1 - 1.0).abs() < 1e-15 && (g[1].1 - 1.0).abs() < 1e-15);
        let g = gauss_legendre(3);
        assert!((g[2].0 - 0.6f64.sqrt()).abs() < 1e-15);
        assert!((g[1].1 - 8.0 / 9.0).abs() < 1e-15);
        assert!((g[0].1 - 5.0 / 9.0).abs() < 1e-15);
        for n in 1..=12 {
            let g = gauss_legendre(n);
            for w in g.windows(2) {
                assert!(w[0].0 < w[1].0, "GL({n}) points not increasing");
            }
            let s: f64 = g.iter().map(|p| p.1).sum();
            assert!((s - 2.0).abs() < 1e-14, "GL({n}) weights sum {s}");
        }
    }

    #[test]
    fn exact_on_monomials_up_to_order() {
        let kinds = [
            ElementKind::Line2,
            ElementKind::Quad4,
            ElementKind::Hex8,
            ElementKind::Tri3,
            ElementKind::Tet4,
        ];
        for kind in kinds {
            for order in 0..=12 {
                // Relative to the reference measure (Newton-computed Gauss-Legendre rules for
                // more than 5 points are accurate to ~1e-15, the closed forms to an ulp).
                let err = max_err(kind, order, order) / exact_monomial(kind, [0, 0, 0]);
                let tol = if points_per_direction(order) <= 5 { 4e-15 } else { 2e-14 };
                assert!(err < tol, "{kind:?} order {order}: relative error {err}");
                for (_, w) in gauss(kind, order) {
                    assert!(w > 0.0, "{kind:?} order {order}: non-positive weight {w}");
                }
            }
        }
        assert!((gauss(ElementKind::Point1, 3)[0].1 - 1.0).abs() == 0.0);
    }

    #[test]
    fn tensor_rules_exact_per_direction() {
        // q points per direction integrate x^a y^b z^c exactly for a, b, c <= 2q - 1.
        for order in 0..=9 {
            let q = points_per_direction(order);
            assert_eq!(gauss(ElementKind::Quad4, order).len(), q * q);
            assert_eq!(gauss(ElementKind::Hex8, order).len(), q * q * q);
            let m = 2 * q - 1;
            let rule = gauss(ElementKind::Hex8, order);
            for e in [[m, m, m], [m, 0, m - m % 2]] {
                let err = (integrate(&rule, e) - exact_monomial(ElementKind::Hex8, e)).abs();
                assert!(err < 1e-14, "order {order} {e:?}: {err}");
            }
        }
    }

    #[test]
    fn rules_are_not_exact_beyond_their_degree() {
        // Sanity check that the exactness test can fail: each simplex rule misses the
        // next degree (so the claimed degree is sharp).
        for (kind, order, degree) in [
            (ElementKind::Tri3, 1, 1),
            (ElementKind::Tri3, 2, 2),
            (ElementKind::Tri3, 4, 4),
            (ElementKind::Tri3, 5, 5),
            (ElementKind::Tet4, 1, 1),
            (ElementKind::Tet4, 2, 2),
            (ElementKind::Tet4, 5, 5),
            (ElementKind::Quad4, 3, 3),
            (ElementKind::Line2, 9, 9),
        ] {
            assert!(max_err(kind, order, degree + 1) > 1e-8, "{kind:?} {order}");
        }
    }

    #[test]
    fn point_counts() {
        let n = |k, o| gauss(k, o).len();
        assert_eq!(n(ElementKind::Tri3, 1), 1);
        assert_eq!(n(ElementKind::Tri3, 2), 3);
        assert_eq!(n(ElementKind::Tri3, 3), 6);
        assert_eq!(n(ElementKind::Tri3, 4), 6);
        assert_eq!(n(ElementKind::Tri3, 5), 7);
        assert_eq!(n(ElementKind::Tet4, 1), 1);
        assert_eq!(n(ElementKind::Tet4, 2), 4);
        assert_eq!(n(ElementKind::Tet4, 5), 14);
        assert_eq!(n(ElementKind::Line2, 5), 3);
        assert_eq!(n(ElementKind::Line2, 9), 5);
    }
}
