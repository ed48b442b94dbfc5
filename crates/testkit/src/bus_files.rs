//! Bus files that the tests of several crates (bus, console, MQTT, service, the tool) run, as
//! YAML text: each test reads it with its own catalogue, so this crate needs none of theirs.

/// The measurement line of the tests: two P series heads facing each other 20 mm apart,
/// `top` at slave 1 and `bottom` at slave 2, on one simulated line (`rs485`, 115200 baud, any
/// format), each polling `distance_1`, and the measurement `gap` = `20mm - top.distance_1 -
/// bottom.distance_1` (the object's thickness between them), its inputs at most 1 s apart.
///
/// Start from [`two_heads_gap`], set what the test needs, and take the YAML from
/// [`text`](Self::text). The line's mapping ends in `any_format: true }`, and it stands on
/// line 3 of the text, where a diagnostic about the line points.
#[derive(Clone, Debug)]
pub struct TwoHeadsGap {
    timeout: Option<String>,
    every: String,
    unit: Option<String>,
    limits: String,
    stats: Option<u32>,
    others: Vec<(String, String)>,
    outputs: Option<String>,
}

/// The measurement line of [`TwoHeadsGap`]: polls every 20 ms, the model's own timeout, no
/// `unit`, limits `{ lo: 9.9mm, hi: 10.1mm }`, no `stats`, no other measurement, no outputs.
pub fn two_heads_gap() -> TwoHeadsGap {
    TwoHeadsGap {
        timeout: None,
        every: "20ms".to_owned(),
        unit: None,
        limits: "{ lo: 9.9mm, hi: 10.1mm }".to_owned(),
        stats: None,
        others: Vec::new(),
        outputs: None,
    }
}

impl TwoHeadsGap {
    /// Each head's `timeout` (`50ms`).
    pub fn timeout(mut self, timeout: &str) -> Self {
        self.timeout = Some(timeout.to_owned());
        self
    }

    /// How often each head's `distance_1` is polled (`50ms`).
    pub fn every(mut self, period: &str) -> Self {
        self.every = period.to_owned();
        self
    }

    /// The gap's `unit` (`mm`).
    pub fn unit(mut self, unit: &str) -> Self {
        self.unit = Some(unit.to_owned());
        self
    }

    /// The gap's `limits`, a YAML flow mapping (`{ lo: 9.9mm, hi: 10.1mm, hh: 12mm }`).
    pub fn limits(mut self, limits: &str) -> Self {
        self.limits = limits.to_owned();
        self
    }

    /// How many of the gap's last values its statistics cover (`stats`).
    pub fn stats(mut self, values: u32) -> Self {
        self.stats = Some(values);
        self
    }

    /// Another measurement after the gap: `name` computed as `expr`, inputs at most 1 s apart.
    pub fn measurement(mut self, name: &str, expr: &str) -> Self {
        self.others.push((name.to_owned(), expr.to_owned()));
        self
    }

    /// The file's `outputs`, a YAML flow mapping (`{ mqtt: { broker: 127.0.0.1:1883 } }`).
    pub fn outputs(mut self, outputs: &str) -> Self {
        self.outputs = Some(outputs.to_owned());
        self
    }

    /// The bus file's text.
    pub fn text(&self) -> String {
        let timeout = self
            .timeout
            .as_ref()
            .map(|timeout| format!(" timeout: {timeout},"))
            .unwrap_or_default();
        let mut text = "\nlines:\n  - { name: rs485, simulated: true, baud: 115200, any_format: true }\ndevices:\n"
            .to_owned();
        for (name, slave) in [("top", 1), ("bottom", 2)] {
            text += &format!(
                "  - {{ name: {name}, model: p-series, slave: {slave},{timeout} poll: [{{ read: distance_1, every: {} }}] }}\n",
                self.every
            );
        }
        text +=
            "measurements:\n  - name: gap\n    expr: 20mm - top.distance_1 - bottom.distance_1\n";
        if let Some(unit) = &self.unit {
            text += &format!("    unit: {unit}\n");
        }
        text += &format!("    limits: {}\n", self.limits);
        if let Some(stats) = self.stats {
            text += &format!("    stats: {stats}\n");
        }
        // How close the inputs are is a bench's matter, not a test's.
        text += "    max_skew: 1s\n";
        for (name, expr) in &self.others {
            text += &format!("  - name: {name}\n    expr: {expr}\n    max_skew: 1s\n");
        }
        if let Some(outputs) = &self.outputs {
            text += &format!("outputs: {outputs}\n");
        }
        text
    }
}

/// The outputs' tests' bus: one P series head `top` at slave 1 on a simulated line `rs485`,
/// polling nothing; a test appends its `outputs:` section after it.
pub const ONE_HEAD: &str = "
lines:
  - { name: rs485, simulated: true }
devices:
  - { name: top, model: p-series, slave: 1 }
";

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_gap_file_says_what_was_set_and_nothing_else() {
        let text = two_heads_gap()
            .timeout("50ms")
            .unit("mm")
            .limits("{ lo: 9.9mm, hi: 10.1mm, hh: 12mm }")
            .stats(50)
            .measurement("ratio", "top.distance_1 / bottom.distance_1")
            .outputs("{ mqtt: { broker: 127.0.0.1:1883, prefix: plant } }")
            .text();
        let expected = [
            "",
            "lines:",
            "  - { name: rs485, simulated: true, baud: 115200, any_format: true }",
            "devices:",
            "  - { name: top, model: p-series, slave: 1, timeout: 50ms, poll: [{ read: distance_1, every: 20ms }] }",
            "  - { name: bottom, model: p-series, slave: 2, timeout: 50ms, poll: [{ read: distance_1, every: 20ms }] }",
            "measurements:",
            "  - name: gap",
            "    expr: 20mm - top.distance_1 - bottom.distance_1",
            "    unit: mm",
            "    limits: { lo: 9.9mm, hi: 10.1mm, hh: 12mm }",
            "    stats: 50",
            "    max_skew: 1s",
            "  - name: ratio",
            "    expr: top.distance_1 / bottom.distance_1",
            "    max_skew: 1s",
            "outputs: { mqtt: { broker: 127.0.0.1:1883, prefix: plant } }",
        ];
        assert_eq!(text.lines().collect::<Vec<_>>(), expected, "{text}");
        let plain = two_heads_gap().every("50ms").text();
        assert!(
            plain.contains("slave: 1, poll: [{ read: distance_1, every: 50ms }] }"),
            "{plain}"
        );
        assert!(
            !plain.contains("unit:") && !plain.contains("stats:"),
            "{plain}"
        );
        assert!(!plain.contains("outputs:"), "{plain}");
    }
}
