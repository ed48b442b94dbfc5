//! Measurements as readings come: a value once every input was read again, judged and summed
//! up; an input without a value or inputs read too far apart give no value but the reason.

use std::time::{Duration, SystemTime};

use optobus_codec::value::{Fixed, Scale};
use optobus_measure::{
    check, Decimal, Definition, InputInfo, Judgement, Limits, Live, Reading, Settings, Window,
};

const MICRO_MM: Scale = Scale::Decimal { exponent: -6 };

fn live(max_skew: Duration) -> Live {
    let definitions = [
        Definition {
            name: "gap",
            expr: "20mm - top.distance_1 - bottom.distance_1",
            unit: Some("mm"),
        },
        Definition {
            name: "gap_um",
            expr: "gap * 1000",
            unit: Some("mm"),
        },
    ];
    let plan = check(&definitions, |_, _| {
        Ok(InputInfo {
            unit: Some("mm"),
            scale: Some(MICRO_MM),
        })
    })
    .unwrap();
    let settings = Settings {
        limits: Some(Limits {
            lo: Some(Decimal::new(99, -1)),
            hi: Some(Decimal::new(101, -1)),
            ..Limits::default()
        }),
        stats: Some(Window::Count(200)),
        max_skew,
    };
    Live::new(
        plan,
        vec![
            settings.clone(),
            Settings {
                limits: None,
                stats: None,
                ..settings
            },
        ],
    )
}

fn reading(raw: Option<i64>, at: SystemTime) -> Reading {
    Reading {
        value: raw.map(|raw| Fixed::new(raw, MICRO_MM)),
        requested: at,
        reason: raw.is_none().then(|| "top is offline".to_owned()),
    }
}

fn input(live: &Live, name: &str) -> usize {
    live.plan()
        .inputs
        .iter()
        .position(|i| i.to_string() == name)
        .unwrap()
}

#[test]
fn a_value_comes_once_every_input_was_read_again_judged_and_summed_up() {
    let mut live = live(Duration::from_millis(100));
    let (top, bottom) = (
        input(&live, "top.distance_1"),
        input(&live, "bottom.distance_1"),
    );
    let t0 = SystemTime::UNIX_EPOCH + Duration::from_secs(1_800_000_000);
    assert!(live.take(top, reading(Some(4_969_234), t0)).is_empty());
    let outcomes = live.take(
        bottom,
        reading(Some(4_969_136), t0 + Duration::from_micros(2_150)),
    );
    assert_eq!(outcomes.len(), 2, "gap and the measurement made of it");
    let gap = &outcomes[0];
    assert_eq!(gap.value.as_ref().unwrap().to_string(), "10.061630");
    assert_eq!(gap.skew, Duration::from_micros(2_150));
    assert_eq!(gap.judgement, Some(Judgement::Go));
    assert_eq!(gap.stats.unwrap().count, 1);
    assert_eq!(
        outcomes[1].value.as_ref().unwrap().to_string(),
        "10061.630000"
    );
    // The top read again, but not the bottom: no value yet.
    assert!(live
        .take(
            top,
            reading(Some(4_869_234), t0 + Duration::from_millis(20))
        )
        .is_empty());
    let outcomes = live.take(
        bottom,
        reading(Some(4_969_136), t0 + Duration::from_millis(21)),
    );
    assert_eq!(outcomes[0].value.as_ref().unwrap().to_string(), "10.161630");
    assert_eq!(outcomes[0].judgement, Some(Judgement::High));
    assert_eq!(live.counts(0), Some([0, 0, 1, 1, 0]));
    assert_eq!(outcomes[0].stats.unwrap().count, 2);
}

#[test]
fn an_offline_device_makes_its_measurements_invalid_with_the_reason() {
    let mut live = live(Duration::from_millis(100));
    let (top, bottom) = (
        input(&live, "top.distance_1"),
        input(&live, "bottom.distance_1"),
    );
    let t0 = SystemTime::UNIX_EPOCH + Duration::from_secs(1_800_000_000);
    live.take(top, reading(None, t0));
    let outcomes = live.take(bottom, reading(Some(4_969_136), t0));
    assert_eq!(
        outcomes[0].value,
        Err("top.distance_1: top is offline".to_owned())
    );
    assert_eq!(outcomes[1].value, Err("gap has no value".to_owned()));
    assert_eq!(outcomes[0].judgement, None);
    assert_eq!(live.counts(0), Some([0; 5]), "no value is judged");
    // While the top stays offline, each reading of the bottom gives an invalid value again.
    let outcomes = live.take(
        bottom,
        reading(Some(4_969_100), t0 + Duration::from_millis(50)),
    );
    assert_eq!(
        outcomes[0].value,
        Err("top.distance_1: top is offline".to_owned())
    );
}

#[test]
fn inputs_read_further_apart_than_max_skew_give_no_value() {
    let mut live = live(Duration::from_millis(20));
    let (top, bottom) = (
        input(&live, "top.distance_1"),
        input(&live, "bottom.distance_1"),
    );
    let t0 = SystemTime::UNIX_EPOCH + Duration::from_secs(1_800_000_000);
    live.take(top, reading(Some(4_969_234), t0));
    let outcomes = live.take(
        bottom,
        reading(Some(4_969_136), t0 + Duration::from_millis(35)),
    );
    assert_eq!(
        outcomes[0].value,
        Err("its inputs were read 35 ms apart, more than max_skew (20 ms)".to_owned())
    );
    assert_eq!(outcomes[0].skew, Duration::from_millis(35));
}
