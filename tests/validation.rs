//! Every invalid write is refused with a typed error before a byte reaches the wire: for
//! every writable register of every spec in `specs/` (`validation::<family>`, through the
//! driver core the generated setters call, with the spec's runtime description), and through
//! the typed setters themselves.

use optobus_device::{RegisterInfo, ValueKind};
use optobus_driver::transport::{Error as WireError, ReadRequest, WriteValue};
use optobus_driver::{Core, Error, Fixed, Scale, Transport};
use optobus_tests::generated::p_series;
use optobus_tests::specs;

/// A transport that records that it was used and fails.
#[derive(Default)]
struct NoWire {
    calls: usize,
}

impl Transport for NoWire {
    async fn read_words(&mut self, _: u8, _: ReadRequest) -> Result<Vec<u16>, WireError> {
        self.calls += 1;
        Err(WireError::Closed)
    }

    async fn write(&mut self, _: u8, _: u16, _: WriteValue) -> Result<(), WireError> {
        self.calls += 1;
        Err(WireError::Closed)
    }
}

/// Raw values outside the register's range or type, as exact values in its scale.
fn out_of_range(register: &RegisterInfo) -> Vec<i64> {
    let (type_min, type_max) = register.scalar().bounds();
    let (min, max) = register.range.unwrap_or((type_min, type_max));
    vec![min - 1, max + 1]
}

fn block_on<F: std::future::Future>(future: F) -> F::Output {
    tokio::runtime::Builder::new_current_thread()
        .enable_time()
        .build()
        .expect("runtime")
        .block_on(future)
}

optobus_tests::family_cases!(validation, invalid_values_never_reach_the_wire);

fn invalid_values_never_reach_the_wire(family: &str) {
    let mut refused = 0;
    let device = specs::describe(family);
    let mut core = Core::with_default_slave(NoWire::default(), device);
    for register in device.registers {
        let register: &'static RegisterInfo = register;
        if !register.access.writable() {
            let error = block_on(core.write(register, &0u16)).unwrap_err();
            assert!(
                matches!(error, Error::NotAllowed { .. }),
                "{}",
                register.name
            );
            refused += 1;
            continue;
        }
        let scale = register.scale.unwrap_or(Scale::ONE);
        if matches!(register.kind, ValueKind::Scalar(_)) {
            for raw in out_of_range(register) {
                let value = Fixed::new(raw, scale);
                let error = block_on(core.write(register, &value)).unwrap_err();
                assert!(
                    matches!(error, Error::OutOfRange { register: r, .. } if r == register.name),
                    "{}: {raw}: {error}",
                    register.name
                );
                refused += 1;
            }
            if let Scale::Decimal { exponent } = scale {
                let half_step = Fixed::new(
                    5,
                    Scale::Decimal {
                        exponent: exponent - 1,
                    },
                );
                let error = block_on(core.write(register, &half_step)).unwrap_err();
                assert!(
                    matches!(error, Error::NotRepresentable { .. }),
                    "{}: {error}",
                    register.name
                );
                refused += 1;
            }
        }
        if !register.codes.is_empty() {
            let undefined = register.codes.iter().map(|c| c.code).max().unwrap_or(0) + 1;
            let error = optobus_driver::encode_code(register, undefined).unwrap_err();
            assert!(matches!(error, Error::UndefinedCode { code, .. } if code == undefined));
            refused += 1;
        }
        if let ValueKind::Packed(fields) = register.kind {
            for field in fields.iter().filter(|f| !f.codes.is_empty()) {
                let max_code = field.codes.iter().map(|c| c.code).max().unwrap_or(0);
                let limit = if field.width >= 32 {
                    u32::MAX
                } else {
                    (1 << field.width) - 1
                };
                if max_code < limit {
                    let bits = (max_code + 1) << field.lsb;
                    let error = optobus_driver::encode_packed(register, Some(bits)).unwrap_err();
                    assert!(
                        matches!(error, Error::UndefinedCode { field: Some(f), .. } if f == field.name),
                        "{}: {error}",
                        register.name
                    );
                    refused += 1;
                }
            }
        }
    }
    assert_eq!(
        core.transport_mut().calls,
        0,
        "{} touched the wire",
        device.family
    );
    // Every spec has registers; each read-only one alone gives one refusal.
    assert!(refused > 0, "{family}: no refusal checked");
}

#[test]
fn typed_setters_refuse_before_sending() {
    use p_series::{MedianFilterWidth, PSeries, Statistic1Config};
    block_on(async {
        let mut sensor = PSeries::new(NoWire::default(), 1).expect("slave 1");
        // Range: 0.5 % to 100 %.
        let error = sensor
            .set_light_power("100.1".parse().unwrap())
            .await
            .unwrap_err();
        assert_eq!(
            error.to_string(),
            "100.1 % is out of range for `light_power` (0.5 % ..= 100.0 %)"
        );
        // A step of 0.1 %: 50.05 would need rounding.
        let error = sensor
            .set_light_power("50.05".parse().unwrap())
            .await
            .unwrap_err();
        assert!(matches!(error, Error::NotRepresentable { .. }), "{error}");
        // Undefined enum code.
        let error = sensor
            .set_median_filter_width(MedianFilterWidth::Unknown(9))
            .await
            .unwrap_err();
        assert!(
            matches!(error, Error::UndefinedCode { code: 9, .. }),
            "{error}"
        );
        // A packed field with an undefined code.
        let mut config = Statistic1Config::from_raw(0);
        config.statistic_type = p_series::StatisticType::Unknown(0x7F);
        let error = sensor.set_statistic_1_config(config).await.unwrap_err();
        assert!(
            matches!(error, Error::UndefinedCode { field: Some(_), .. }),
            "{error}"
        );
        // Slave address 0 is not a device address.
        let error = sensor.set_slave_address(0).await.unwrap_err();
        assert!(
            matches!(
                error,
                Error::OutOfRange {
                    min: 1,
                    max: 247,
                    ..
                }
            ),
            "{error}"
        );
        assert_eq!(sensor.into_transport().calls, 0);
    });
}
