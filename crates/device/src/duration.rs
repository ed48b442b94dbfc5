//! Durations as specs write them in code meanings (`6.25us`, `1ms`, `2s`): a buffer's
//! sampling interval is such an enum.

/// Seconds in a duration written as `6.25us`, `1ms` or `2s` (`µs` too); `None` for any other
/// text and for durations that are not positive.
pub fn parse_duration(text: &str) -> Option<f64> {
    let text = text.trim();
    let (number, per_second) = if let Some(n) = text.strip_suffix("us") {
        (n, 1e6)
    } else if let Some(n) = text.strip_suffix("µs") {
        (n, 1e6)
    } else if let Some(n) = text.strip_suffix("ms") {
        (n, 1e3)
    } else if let Some(n) = text.strip_suffix('s') {
        (n, 1.0)
    } else {
        return None;
    };
    let value: f64 = number.trim().parse().ok()?;
    (value > 0.0).then_some(value / per_second)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn durations() {
        assert_eq!(parse_duration("6.25us"), Some(6.25e-6));
        assert_eq!(parse_duration("1ms"), Some(1e-3));
        assert_eq!(parse_duration("2s"), Some(2.0));
        assert_eq!(parse_duration("=1 5Hz"), None);
        assert_eq!(parse_duration("us"), None);
        assert_eq!(parse_duration("0ms"), None);
    }
}
