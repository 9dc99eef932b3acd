//! The process's clock as the protocol core's time (style.md practice 2: own the time type,
//! convert at the edge).

use devicenet::{Duration, Instant};

/// A monotonic clock that reads [`Instant`]s: microseconds since [`Clock::start`]. Copies share
/// the same origin, so the serial threads and the main loop agree on every timestamp.
#[derive(Clone, Copy, Debug)]
pub struct Clock {
    origin: std::time::Instant,
}

impl Clock {
    /// A clock whose zero is now.
    pub fn start() -> Clock {
        Clock { origin: std::time::Instant::now() }
    }

    /// The time since the clock started.
    pub fn now(&self) -> Instant {
        Instant::from_micros(u64::try_from(self.origin.elapsed().as_micros()).unwrap_or(u64::MAX))
    }
}

/// A core duration as a standard one.
pub fn to_std(d: Duration) -> std::time::Duration {
    std::time::Duration::from_micros(d.total_micros())
}

/// Seconds as a core duration (command-line values): finite and not negative.
pub fn from_secs_f64(secs: f64) -> Option<Duration> {
    if !(0.0..=1e9).contains(&secs) {
        return None;
    }
    Some(Duration::from_micros((secs * 1e6).round() as u64))
}

/// `secs.micros` with six decimals, as in `candump -L` logs.
pub fn format_instant(at: Instant) -> String {
    let us = at.total_micros();
    format!("{}.{:06}", us / 1_000_000, us % 1_000_000)
}

#[cfg(test)]
mod tests {
    use super::*;
    use rstest::rstest;

    #[test]
    fn clock_moves_forward() {
        let c = Clock::start();
        let a = c.now();
        std::thread::sleep(std::time::Duration::from_millis(2));
        let b = c.now();
        assert!(b > a);
        assert!((b - a).total_micros() >= 2000);
    }

    #[rstest]
    #[case::zero(0.0, Some(0))]
    #[case::fraction(1.5, Some(1_500_000))]
    #[case::negative(-1.0, None)]
    #[case::nan(f64::NAN, None)]
    #[case::infinite(f64::INFINITY, None)]
    fn seconds(#[case] secs: f64, #[case] micros: Option<u64>) {
        assert_eq!(from_secs_f64(secs).map(|d| d.total_micros()), micros);
    }

    #[test]
    fn formatting() {
        assert_eq!(format_instant(Instant::from_micros(5_000_423)), "5.000423");
        assert_eq!(to_std(Duration::from_millis(3)), std::time::Duration::from_millis(3));
    }
}
