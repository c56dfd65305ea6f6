//! Everything the user reads goes through here: only rank 0 prints. A progress bar with step,
//! simulated time and ETA on a terminal; plain periodic lines otherwise (logs, CI).

use std::io::IsTerminal;
use std::time::{Duration, Instant};

pub struct Console {
    pub rank: usize,
    pub quiet: bool,
}

impl Console {
    pub fn new(rank: usize, quiet: bool) -> Console {
        Console { rank, quiet }
    }
    /// A line on stdout from rank 0.
    pub fn say(&self, msg: impl AsRef<str>) {
        if self.rank == 0 && !self.quiet {
            println!("{}", msg.as_ref());
        }
    }
    /// A warning on stderr from rank 0, even when quiet: `massfree: warning: ...`.
    pub fn warn(&self, msg: impl AsRef<str>) {
        if self.rank == 0 {
            eprintln!("massfree: warning: {}", msg.as_ref());
        }
    }
    /// A line on stdout from rank 0 even when quiet (results, summaries).
    pub fn result(&self, msg: impl AsRef<str>) {
        if self.rank == 0 {
            println!("{}", msg.as_ref());
        }
    }
}

pub struct Progress {
    bar: Option<indicatif::ProgressBar>,
    plain: bool,
    total: usize,
    start: Instant,
    last_line: Instant,
}

impl Progress {
    pub fn new(console: &Console, total: usize, enabled: bool) -> Progress {
        let active = enabled && console.rank == 0 && !console.quiet;
        let tty = std::io::stderr().is_terminal();
        let bar = if active && tty {
            let b = indicatif::ProgressBar::new(total as u64);
            b.set_style(
                indicatif::ProgressStyle::with_template(
                    "{bar:30} step {pos}/{len}  {msg}  elapsed {elapsed_precise}  ETA {eta_precise}",
                )
                .expect("progress template"),
            );
            Some(b)
        } else {
            None
        };
        Progress {
            bar,
            plain: active && !tty,
            total,
            start: Instant::now(),
            last_line: Instant::now(),
        }
    }

    /// Report step `n` done at simulated time `t`; `drift` is the energy balance residual.
    /// Step `n` at time `t` done, the energy balance so far `drift`; `newton`: finite strain's
    /// Newton iterations per step so far.
    pub fn update(&mut self, n: usize, t: f64, drift: f64, newton: Option<f64>) {
        let newton = newton.map(|x| format!("  Newton {x:.2} its/step")).unwrap_or_default();
        if let Some(b) = &self.bar {
            b.set_position(n as u64);
            b.set_message(format!("t = {t:.4e}  energy balance {drift:.1e}{newton}"));
        } else if self.plain {
            let now = Instant::now();
            if now.duration_since(self.last_line) >= Duration::from_secs(10) || n == self.total {
                self.last_line = now;
                let el = now.duration_since(self.start).as_secs_f64();
                let eta = if n > 0 { el / n as f64 * (self.total - n) as f64 } else { 0.0 };
                eprintln!(
                    "step {n}/{}  t = {t:.4e}  energy balance {drift:.1e}{newton}  elapsed {el:.1} s  ETA {eta:.1} s",
                    self.total
                );
            }
        }
    }

    pub fn finish(&mut self) {
        if let Some(b) = self.bar.take() {
            b.finish_and_clear();
        }
    }
}

/// A simulated time as the user reads it: 12 significant digits, trailing zeros dropped, so
/// that a sum of steps prints `3e-5`, not `3.0000000000000004e-5`.
pub fn time(t: f64) -> String {
    let s = format!("{t:.11e}");
    match s.split_once('e') {
        Some((mantissa, exp)) if mantissa.contains('.') => {
            let m = mantissa.trim_end_matches('0').trim_end_matches('.');
            format!("{m}e{exp}")
        }
        _ => s,
    }
}

#[cfg(test)]
mod tests {
    #[test]
    fn times_print_without_rounding_noise() {
        assert_eq!(super::time(3.0000000000000004e-5), "3e-5");
        assert_eq!(super::time(9.999999999999999e-5), "1e-4");
        assert_eq!(super::time(1.8400000000000002e1), "1.84e1");
        assert_eq!(super::time(0.0), "0e0");
        assert_eq!(super::time(-2.5e-3), "-2.5e-3");
        assert_eq!(super::time(1.23456789012345e-7), "1.23456789012e-7");
    }
}
