//! The exposition formats: OpenMetrics, as prometheus-client writes it, and the Prometheus
//! text format 0.0.4 that every scraper and `promtool check metrics` read.

/// The content type of the Prometheus text format.
pub const PROMETHEUS_TEXT_TYPE: &str = "text/plain; version=0.0.4; charset=utf-8";

/// The content type of OpenMetrics text.
pub const OPENMETRICS_TYPE: &str = "application/openmetrics-text; version=1.0.0; charset=utf-8";

/// OpenMetrics text in the Prometheus text format. They differ where counters are: OpenMetrics
/// names a counter family `x` (`# TYPE x counter`) and its sample `x_total`, while the
/// Prometheus format names both `x_total`; read as Prometheus text, the sample would be a
/// family of its own, untyped and without help. `# UNIT` and `# EOF` are OpenMetrics only.
pub fn prometheus_text(openmetrics: &str) -> String {
    let counters: Vec<&str> = openmetrics
        .lines()
        .filter_map(|line| line.strip_prefix("# TYPE "))
        .filter_map(|rest| rest.strip_suffix(" counter"))
        .collect();
    let mut text = String::with_capacity(openmetrics.len() + 16 * counters.len());
    for line in openmetrics.lines() {
        if line == "# EOF" || line.starts_with("# UNIT ") {
            continue;
        }
        let renamed = ["# HELP ", "# TYPE "].iter().find_map(|tag| {
            let rest = line.strip_prefix(tag)?;
            let (name, tail) = rest.split_once(' ')?;
            counters
                .contains(&name)
                .then(|| format!("{tag}{name}_total {tail}"))
        });
        match renamed {
            Some(line) => text.push_str(&line),
            None => text.push_str(line),
        }
        text.push('\n');
    }
    text
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn counter_families_take_the_total_name_of_their_samples() {
        let openmetrics = "# HELP a_requests Requests.\n# TYPE a_requests counter\n\
                           a_requests_total{line=\"x\"} 5\n# HELP b_up Up.\n# TYPE b_up gauge\n\
                           b_up 1\n# EOF\n";
        assert_eq!(
            prometheus_text(openmetrics),
            "# HELP a_requests_total Requests.\n# TYPE a_requests_total counter\n\
             a_requests_total{line=\"x\"} 5\n# HELP b_up Up.\n# TYPE b_up gauge\nb_up 1\n"
        );
    }
}
