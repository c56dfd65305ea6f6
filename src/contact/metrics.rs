//! Chatter of contact pressures, as numbers (docs/method.md, chatter and impacts).
//!
//! - `osc2`: the period-2 amplitude of a node's pressure history over its contact period,
//!   `RMS_n(p^{n+1} - 2 p^n + p^{n-1}) / 4 / max_n p^n`: a saw-tooth `+-a` around a smooth curve
//!   gives `a / max p`.
//! - `tv_index`: `TV(p) / (2 max p)` over the contact period: 1 for a single smooth hump.
//! - `episodes`: how many times a node enters contact.

/// First and last index where `active` holds (the contact period), if any.
pub fn contact_period(active: &[bool]) -> Option<(usize, usize)> {
    let first = active.iter().position(|&a| a)?;
    let last = active.iter().rposition(|&a| a)?;
    Some((first, last))
}

/// Period-2 amplitude of `p` over `[first, last]`, relative to its maximum.
pub fn osc2(p: &[f64], period: (usize, usize)) -> f64 {
    let (a, b) = period;
    if b < a + 2 {
        return 0.0;
    }
    let pmax = p[a..=b].iter().fold(0.0f64, |m, &x| m.max(x.abs()));
    if pmax == 0.0 {
        return 0.0;
    }
    let second: Vec<f64> = (a + 1..b).map(|n| p[n + 1] - 2.0 * p[n] + p[n - 1]).collect();
    let rms = (second.iter().map(|x| x * x).sum::<f64>() / second.len() as f64).sqrt();
    rms / 4.0 / pmax
}

/// Total variation of `p` over `[first - 1, last + 1]` (from and back to zero) over twice its
/// maximum.
pub fn tv_index(p: &[f64], period: (usize, usize)) -> f64 {
    let (a, b) = period;
    let lo = a.saturating_sub(1);
    let hi = (b + 1).min(p.len() - 1);
    let pmax = p[lo..=hi].iter().fold(0.0f64, |m, &x| m.max(x.abs()));
    if pmax == 0.0 {
        return 0.0;
    }
    let tv: f64 = (lo..hi).map(|n| (p[n + 1] - p[n]).abs()).sum();
    tv / (2.0 * pmax)
}

/// Number of contact episodes (inactive -> active transitions, counting a start in contact).
pub fn episodes(active: &[bool]) -> usize {
    let mut n = 0;
    let mut prev = false;
    for &a in active {
        if a && !prev {
            n += 1;
        }
        prev = a;
    }
    n
}

#[cfg(test)]
mod tests {
    use super::*;

    fn hump(n: usize) -> Vec<f64> {
        (0..n).map(|i| (std::f64::consts::PI * i as f64 / (n - 1) as f64).sin()).collect()
    }

    #[test]
    fn smooth_hump_has_tiny_osc2_and_tv_index_one() {
        let p = hump(201);
        let period = (1, 199);
        assert!(osc2(&p, period) < 1e-3);
        assert!((tv_index(&p, period) - 1.0).abs() < 1e-3);
    }

    #[test]
    fn sawtooth_amplitude_is_measured() {
        let a = 0.05;
        let p: Vec<f64> = hump(201)
            .iter()
            .enumerate()
            .map(|(i, x)| x + if i % 2 == 0 { a } else { -a })
            .collect();
        let o = osc2(&p, (1, 199));
        assert!((o - a / 1.05).abs() < 0.003, "osc2 {o}");
        assert!(tv_index(&p, (1, 199)) > 5.0);
    }

    #[test]
    fn episodes_and_period() {
        let act = [false, true, true, false, true, false, false, true];
        assert_eq!(episodes(&act), 3);
        assert_eq!(contact_period(&act), Some((1, 7)));
        assert_eq!(contact_period(&[false, false]), None);
        assert_eq!(episodes(&[true, true]), 1);
    }
}
