//! Space-time separation of load expressions: `f(x, t) = sum_k s_k(t) g_k(x)`.
//!
//! Loads like the beam's `(...x...)*sin(2*pi*t)` are assembled once per distinct time factor
//! `s_k` and combined every step with a few vector updates, instead of integrating the
//! expression over every element at every step.
//!
//! The split walks the expression's parse tree ([`Node`], constants folded):
//! - a sum `a + b`, `a - b` splits into its terms (the chain of `+`/`-`; a parenthesized sum or
//!   a negated sum is split too when it mixes x and t);
//! - a term is a product `f_1 * f_2 * ...`: factors depending on t only go to `s_k`, the others
//!   (x only, or constant) to `g_k`;
//! - a factor depending on both is split further through `*`, `/`, a sign and an integer power:
//!   `x*t/y = t * (x/y)`, `(x*sin(t))^2 = sin(t)^2 * x^2`; anything else (`sin(x*t)`,
//!   `(x + t)*y`) does not separate.
//!
//! A factor depending on one side only is kept whole (the chains above are written back in
//! their order and association), so the factors evaluate to the bit as they did in the
//! original text; the texts of [`Term`] are the factors' trees written out ([`Node`]'s
//! `Display`), so equal time factors group together however they were spaced.

use super::expr::{parse_tree, Bin, Node, Un};

/// One separated term: `sign * time(t) * space(x)`; `time` is "1" for a steady term.
/// `time` and `space` are expression texts that may be multiplied or prefixed with a sign as
/// they are (a sum comes parenthesized).
#[derive(Debug, Clone, PartialEq)]
pub struct Term {
    pub sign: f64,
    pub time: String,
    pub space: String,
}

/// Separate `src` into terms, or None if it does not parse or some term mixes x and t in a way
/// the split cannot undo.
pub fn separate(src: &str) -> Option<Vec<Term>> {
    let tree = parse_tree(src).ok()?;
    let mut terms = Vec::new();
    sum(&tree, 1.0, &mut terms)?;
    Some(terms)
}

/// A product split as `sign * time * space`; `None` stands for the factor 1.
struct Split {
    sign: f64,
    time: Option<Node>,
    space: Option<Node>,
}

/// `a op b`, where a missing operand is 1: `1*b = b`, `a/1 = a`, `1/b` stays a quotient.
fn combine(op: Bin, a: Option<Node>, b: Option<Node>) -> Option<Node> {
    match (a, b) {
        (a, None) => a,
        (None, Some(b)) if op == Bin::Mul => Some(b),
        (a, Some(b)) => Some(Node::Bin(op, Box::new(a.unwrap_or(Node::Num(1.0))), Box::new(b))),
    }
}

impl Split {
    /// `self op other` (`op` is `*` or `/`), time with time and space with space.
    fn with(self, op: Bin, other: Split) -> Split {
        Split {
            sign: self.sign * other.sign,
            time: combine(op, self.time, other.time),
            space: combine(op, self.space, other.space),
        }
    }

    /// `(s a b)^p = s^p a^p b^p` for an integer `p`.
    fn powi(self, p: f64) -> Split {
        let pow =
            |n: Option<Node>| n.map(|n| Node::Bin(Bin::Pow, Box::new(n), Box::new(Node::Num(p))));
        Split {
            sign: if p % 2.0 == 0.0 { 1.0 } else { self.sign },
            time: pow(self.time),
            space: pow(self.space),
        }
    }
}

/// The terms of a sum chain `a +- b +- c ...`.
fn sum(n: &Node, sign: f64, out: &mut Vec<Term>) -> Option<()> {
    match n {
        Node::Bin(Bin::Add, a, b) => {
            sum(a, sign, out)?;
            term(b, sign, out)
        }
        Node::Bin(Bin::Sub, a, b) => {
            sum(a, sign, out)?;
            term(b, -sign, out)
        }
        _ => term(n, sign, out),
    }
}

/// One term; a sum inside it (parenthesized, or negated) is opened only when it mixes x and t,
/// so that a one-sided sum stays whole.
fn term(n: &Node, sign: f64, out: &mut Vec<Term>) -> Option<()> {
    if n.depends_on_x() && n.depends_on_t() {
        match n {
            Node::Bin(Bin::Add | Bin::Sub, ..) => return sum(n, sign, out),
            Node::Un(Un::Neg, a) => return term(a, -sign, out),
            _ => {}
        }
    }
    let p = product(n)?;
    out.push(Term { sign: sign * p.sign, time: text(p.time), space: text(p.space) });
    Some(())
}

/// A product chain `f_1 * f_2 * ...`, factor by factor (also when it depends on one side only,
/// so that constant factors of a time-only term go to the space part).
fn product(n: &Node) -> Option<Split> {
    match n {
        Node::Bin(Bin::Mul, a, b) => Some(product(a)?.with(Bin::Mul, split(b)?)),
        _ => split(n),
    }
}

/// One factor: whole if it depends on one side only, else split through `*`, `/`, `-`, `^n`.
fn split(n: &Node) -> Option<Split> {
    let (x, t) = (n.depends_on_x(), n.depends_on_t());
    if !(x && t) {
        let (time, space) = if t { (Some(n.clone()), None) } else { (None, Some(n.clone())) };
        return Some(Split { sign: 1.0, time, space });
    }
    match n {
        Node::Bin(Bin::Mul, ..) => product(n),
        Node::Bin(Bin::Div, a, b) => Some(split(a)?.with(Bin::Div, split(b)?)),
        Node::Un(Un::Neg, a) => split(a).map(|s| Split { sign: -s.sign, ..s }),
        Node::Bin(Bin::Pow, a, b) => match **b {
            Node::Num(p) if p.is_finite() && p.fract() == 0.0 => Some(split(a)?.powi(p)),
            _ => None,
        },
        _ => None,
    }
}

/// The text of a factor ("1" when absent); a sum is parenthesized so that the caller may
/// prefix a sign or multiply.
fn text(n: Option<Node>) -> String {
    match n {
        None => "1".to_string(),
        Some(n @ Node::Bin(Bin::Add | Bin::Sub, ..)) => format!("({n})"),
        Some(n) => n.to_string(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::expr::Expr;

    fn check(src: &str) {
        let terms = separate(src).unwrap_or_else(|| panic!("{src} should separate"));
        let e = Expr::parse(src).unwrap();
        for &(x, y, z, t) in &[(0.3, 0.7, 0.1, 0.013), (3.0, 0.2, 0.9, 0.41), (9.5, 1.0, 0.5, 1.7)]
        {
            let mut sum = 0.0;
            for term in &terms {
                let s = Expr::parse(&term.time).unwrap();
                let g = Expr::parse(&term.space).unwrap();
                assert!(!s.depends_on_x() && !g.depends_on_t());
                sum += term.sign * s.eval([x, y, z], t) * g.eval([x, y, z], t);
            }
            let exact = e.eval([x, y, z], t);
            assert!((sum - exact).abs() <= 1e-12 * exact.abs().max(1.0), "{src}: {sum} vs {exact}");
        }
    }

    #[test]
    fn beam_loads_separate() {
        check("200/13*y*(x - 5)*sin(2*pi*t)");
        check("(0.08*pi^2*x*y^2*(x - 10) + 140/13*x*(x - 10) + 40/13*y^2)*sin(2*pi*t)");
        check("40/13*(5 - x)*sin(2*pi*t)");
        check("-60/13*x*z*(x - 10)*sin(2*pi*t)");
    }

    #[test]
    fn sums_signs_and_exponents() {
        check("x*sin(t) - 2e-3*y*cos(t) + 3");
        check("1.5e+2*x - t^2*y");
        check("-x*exp(-t) + y");
        check("x - (-t)*y");
        assert_eq!(separate("3").unwrap().len(), 1);
    }

    #[test]
    fn mixed_factors_do_not_separate() {
        assert!(separate("sin(x*t)").is_none());
        assert!(separate("x*sin(2*pi*(t - x))").is_none());
        assert!(separate("(x + t)*y").is_none());
    }

    #[test]
    fn forms_the_text_split_missed() {
        // Division, negated and parenthesized mixed sums, integer powers of products.
        check("x*t/y");
        check("t/x");
        check("2*x/t*y");
        check("-(x*t)");
        check("-(x*sin(t) - y)");
        check("(x*cos(t) + y)");
        check("x - (t*y - z*t^2)");
        check("(x*sin(t))^2");
        check("pow(-x*t, 3)/y");
        let terms = separate("x*t/2").unwrap();
        assert_eq!(terms, vec![Term { sign: 1.0, time: "t".into(), space: "x/2".into() }]);
        let terms = separate("-(x*t - y)").unwrap();
        assert_eq!(terms.iter().map(|t| t.sign).collect::<Vec<_>>(), vec![-1.0, 1.0]);
        // Time factors are written canonically, so spacing does not make distinct groups.
        assert_eq!(separate("x*sin(2 * pi*t)"), separate("x*sin(2*pi*t)"));
        // Still not separable: a non-integer power of a product, a mixed sum as a factor.
        assert!(separate("(x*t)^0.5").is_none());
        assert!(separate("2*(x*t + y)").is_none());
        assert!(separate("1 +").is_none());
    }

    /// The shipped scenes' loads (scenes/*.toml) give bit for bit the factors the former
    /// text-based split gave (listed here as it wrote them).
    #[test]
    fn shipped_loads_factor_exactly_as_before() {
        let before = [
            ("200/13*y*(x - 5)*sin(2*pi*t)", "(200/13)*(y)*((x - 5))"),
            (
                "(0.08*pi^2*x*y^2*(x - 10) + 140/13*x*(x - 10) + 40/13*y^2)*sin(2*pi*t)",
                "((0.08*pi^2*x*y^2*(x - 10) + 140/13*x*(x - 10) + 40/13*y^2))",
            ),
            ("40/13*(5 - x)*sin(2*pi*t)", "(40/13)*((5 - x))"),
            ("140/13*x*(10 - x)*sin(2*pi*t)", "(140/13)*(x)*((10 - x))"),
            ("40/13*z^2*(5 - x)*sin(2*pi*t)", "(40/13)*(z^2)*((5 - x))"),
            ("140/13*x*z*(10 - x)*sin(2*pi*t)", "(140/13)*(x)*(z)*((10 - x))"),
            ("-60/13*x*z*(x - 10)*sin(2*pi*t)", "(-60/13)*(x)*(z)*((x - 10))"),
        ];
        let old_time = Expr::parse("(sin(2*pi*t))").unwrap();
        for (src, old_space) in before {
            let terms = separate(src).unwrap();
            assert_eq!(terms.len(), 1, "{src}");
            // As src/assembly combines them: the sign written in front of the space part.
            let space = Expr::parse(&format!("+{}", terms[0].space)).unwrap();
            let time = Expr::parse(&terms[0].time).unwrap();
            let old_space = Expr::parse(&format!("+{old_space}")).unwrap();
            for (x, t) in
                [([0.3, 0.7, 0.1], 0.013), ([3.0, 0.2, 0.9], 0.41), ([9.5, 1.0, 0.5], 1.7)]
            {
                assert_eq!(space.eval(x, t).to_bits(), old_space.eval(x, t).to_bits(), "{src}");
                assert_eq!(time.eval(x, t).to_bits(), old_time.eval(x, t).to_bits(), "{src}");
            }
        }
        let zero = separate("0").unwrap();
        assert_eq!(zero, vec![Term { sign: 1.0, time: "1".into(), space: "0".into() }]);
    }
}
