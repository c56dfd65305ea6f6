//! Space-time separation of load expressions: `f(x, t) = sum_k s_k(t) g_k(x)`.
//!
//! Loads like the beam's `(...x...)*sin(2*pi*t)` are assembled once per distinct time factor
//! `s_k` and combined every step with a few vector updates, instead of integrating the
//! expression over every element at every step. The split is syntactic: an expression is read
//! as a sum of terms (top-level binary `+`/`-`), each term as a product of factors (top-level
//! `*`); a term separates when every factor depends on x only or on t only.

use super::expr::Expr;

/// One separated term: `sign * time(t) * space(x)`; `time` is "1" for a steady term.
#[derive(Debug, Clone, PartialEq)]
pub struct Term {
    pub sign: f64,
    pub time: String,
    pub space: String,
}

/// Split at depth-0 occurrences of the operators `ops` (binary ones only for `+`/`-`).
/// Returns (operator before the piece, piece).
fn split_top(src: &str, ops: &[char]) -> Vec<(char, String)> {
    let chars: Vec<char> = src.chars().collect();
    let mut out = Vec::new();
    let mut depth = 0i32;
    let mut start = 0usize;
    let mut op_before = '+';
    for i in 0..chars.len() {
        let c = chars[i];
        match c {
            '(' => depth += 1,
            ')' => depth -= 1,
            _ if depth == 0 && ops.contains(&c) => {
                if (c == '+' || c == '-') && !is_binary_sign(&chars, i) {
                    continue;
                }
                out.push((op_before, chars[start..i].iter().collect::<String>()));
                op_before = c;
                start = i + 1;
            }
            _ => {}
        }
    }
    out.push((op_before, chars[start..].iter().collect::<String>()));
    out
}

/// Whether the `+`/`-` at `i` is a binary operator (not a unary sign, not an exponent's sign).
fn is_binary_sign(chars: &[char], i: usize) -> bool {
    let mut j = i;
    while j > 0 && chars[j - 1].is_whitespace() {
        j -= 1;
    }
    if j == 0 {
        return false;
    }
    let p = chars[j - 1];
    if !(p.is_alphanumeric() || p == ')' || p == '.' || p == '_') {
        return false; // after an operator or '(' or ',': unary
    }
    // "2e-3": the sign of a number's exponent.
    if (p == 'e' || p == 'E') && j >= 2 {
        let mut k = j - 1;
        while k > 0 && (chars[k - 1].is_ascii_digit() || chars[k - 1] == '.') {
            k -= 1;
        }
        let starts_number =
            k < j - 1 && (k == 0 || !(chars[k - 1].is_alphanumeric() || chars[k - 1] == '_'));
        if starts_number {
            return false;
        }
    }
    true
}

/// Separate `src` into terms, or None if some term mixes x and t in one factor.
pub fn separate(src: &str) -> Option<Vec<Term>> {
    let mut terms = Vec::new();
    for (op, term) in split_top(src, &['+', '-']) {
        let term = term.trim();
        if term.is_empty() {
            // A leading unary sign ("-a*b") leaves an empty first piece.
            if op == '+' {
                continue;
            }
            return None;
        }
        let sign = if op == '-' { -1.0 } else { 1.0 };
        let (mut time, mut space) = (Vec::new(), Vec::new());
        for (_, factor) in split_top(term, &['*']) {
            let e = Expr::parse(&factor).ok()?;
            match (e.depends_on_x(), e.depends_on_t()) {
                (true, true) => return None,
                (false, true) => time.push(format!("({})", factor.trim())),
                _ => space.push(format!("({})", factor.trim())),
            }
        }
        let join = |v: Vec<String>| if v.is_empty() { "1".to_string() } else { v.join("*") };
        terms.push(Term { sign, time: join(time), space: join(space) });
    }
    // A term that starts with a unary minus, e.g. "-(a)*b", parses as a factor "-(a)": fine.
    Some(terms)
}

#[cfg(test)]
mod tests {
    use super::*;

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
}
