//! Which line of a bus file a tool serves when the user names none, or names one.

use std::path::Path;

use optobus_bus::{BusFile, Catalogue, LinePickError};

fn file(text: &str) -> BusFile {
    let catalogue = Catalogue::new([&optobus_p_series::DEVICE]);
    BusFile::parse("bus.yaml", text, Path::new("."), &catalogue)
        .unwrap_or_else(|e| panic!("{}", e.render()))
}

const TWO_LINES: &str = "
lines:
  - { name: plant, serial: /dev/ttyUSB0, baud: 115200, any_format: true }
  - { name: bench, simulated: true, baud: 115200, any_format: true }
devices:
  - { name: top, model: p-series, slave: 1, line: plant, poll: [{ read: light_power }] }
  - { name: side, model: p-series, slave: 2, line: bench, poll: [{ read: light_power }] }
";

#[test]
fn a_line_is_picked_by_name_or_as_the_only_simulated_one() {
    let two = file(TWO_LINES);
    assert_eq!(two.pick_line(Some("plant")), Ok(0));
    assert_eq!(two.pick_line(None), Ok(1));
    assert_eq!(
        two.pick_line(Some("lab")),
        Err(LinePickError::NoSuchLine {
            name: "lab".into(),
            lines: vec!["plant".into(), "bench".into()],
        })
    );
    let neither = file(&TWO_LINES.replace("simulated: true", "serial: /dev/ttyUSB1"));
    assert_eq!(
        neither.pick_line(None),
        Err(LinePickError::Several {
            lines: vec!["plant".into(), "bench".into()],
        })
    );
    let one = file(
        &TWO_LINES
            .replace("\n  - { name: bench", "\n  #")
            .replace("line: bench", "line: plant"),
    );
    assert_eq!(one.pick_line(None), Ok(0));
}
