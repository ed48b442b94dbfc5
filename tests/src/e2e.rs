//! End-to-end helpers: connect a driver to a simulator through real bytes, and sweep every
//! register of a device through the driver core the generated methods call.

use optobus_device::{DeviceInfo, RegisterInfo, Table, ValueKind};
use optobus_driver::transport::{RtuClient, RtuConfig, TcpClient};
use optobus_driver::{
    encode_code, encode_packed, rtu_config, tcp_config, Core, Decode, Encode, Error, Fixed, Scale,
    Transport,
};
use optobus_simulator::{Simulator, TcpServer};
use tokio::io::DuplexStream;

/// Our RTU client on an in-memory line to `sim`, configured from the device description
/// (without line timing: the line is memory).
pub fn rtu(sim: &Simulator) -> RtuClient<DuplexStream> {
    let (stream, _server) = sim.duplex();
    let config = RtuConfig {
        line: None,
        ..rtu_config(sim.device())
    };
    RtuClient::with_config(stream, config)
}

/// A simulator of `device` whose readings are always valid (no invalid-reading sentinels), and
/// our RTU client on an in-memory line to it.
pub fn simulated(device: &'static DeviceInfo) -> (Simulator, RtuClient<DuplexStream>) {
    let sim = Simulator::new(device).sentinel_every(0);
    let client = rtu(&sim);
    (sim, client)
}

/// Our Modbus TCP client connected to `sim` served on 127.0.0.1 (keep the server).
pub async fn tcp(sim: &Simulator) -> (TcpClient, TcpServer) {
    let server = sim.serve_tcp("127.0.0.1:0").await.expect("serve TCP");
    let client = TcpClient::connect(server.local_addr(), tcp_config(sim.device()))
        .await
        .expect("connect");
    (client, server)
}

/// Raw words that a value occupies, to compare what was written with what is read back.
struct Words(Vec<u16>);

impl Encode for Words {
    fn encode(&self, _: &'static RegisterInfo) -> Result<Vec<u16>, Error> {
        Ok(self.0.clone())
    }
}

/// Registers a sweep leaves alone: command registers (writing them acts, it does not set)
/// and the slave address (the device would move away from the driver).
fn sweepable(device: &DeviceInfo, register: &RegisterInfo) -> bool {
    let base = register.member_name().unwrap_or(register.name);
    !device
        .commands
        .iter()
        .any(|c| c.register == register.name || c.register == base)
        && register.name != "slave_address"
}

/// Valid values for a register, as validated words: range ends and middle, every code,
/// every code of each packed field.
pub fn valid_values(register: &'static RegisterInfo) -> Vec<Vec<u16>> {
    let scale = register.scale.unwrap_or(Scale::ONE);
    let mut values = Vec::new();
    match register.kind {
        ValueKind::Bool => {
            values.push(true.encode(register));
            values.push(false.encode(register));
        }
        ValueKind::Enum => {
            values.extend(register.codes.iter().map(|c| encode_code(register, c.code)));
        }
        // A register that lists its values takes those and no other.
        ValueKind::Scalar(_) if !register.allowed_values.is_empty() => {
            for &raw in register.allowed_values {
                values.push(Fixed::new(raw, scale).encode(register));
            }
        }
        ValueKind::Scalar(scalar) => {
            let (type_min, type_max) = scalar.bounds();
            let (min, max) = register.range.unwrap_or((type_min, type_max));
            for raw in [min, max, min + (max - min) / 3] {
                values.push(Fixed::new(raw, scale).encode(register));
            }
        }
        ValueKind::Packed(fields) => {
            // Every field at its first code or lowest value, then each field varied alone.
            let choices = |f: &optobus_device::FieldInfo| -> Vec<u32> {
                match f.range {
                    _ if !f.codes.is_empty() => f.codes.iter().map(|c| c.code).collect(),
                    Some((min, max)) => vec![min as u32, max as u32],
                    None => vec![0],
                }
            };
            let base: u32 = fields.iter().map(|f| choices(f)[0] << f.lsb).sum();
            for field in fields {
                for value in choices(field) {
                    let bits = field.bit_field().set(base, value);
                    values.push(encode_packed(register, bits));
                }
            }
        }
        ValueKind::Ipv4 => {
            values.push(std::net::Ipv4Addr::new(10, 1, 2, 3).encode(register));
        }
        ValueKind::Version(_) | ValueKind::Record(_) => {}
    }
    values
        .into_iter()
        .map(|v| v.unwrap_or_else(|e| panic!("{}: a valid value was refused: {e}", register.name)))
        .collect()
}

/// Reads `register` alone; panics unless every one of its words came back.
pub async fn read_whole<T: Transport>(
    core: &mut Core<T>,
    register: &'static RegisterInfo,
) -> Vec<u16> {
    let words = core
        .read_words(register)
        .await
        .unwrap_or_else(|e| panic!("{}: {e}", register.name));
    assert_eq!(
        words.len(),
        usize::from(register.words),
        "{}",
        register.name
    );
    words
}

/// Reads every readable register, one request each, and checks what came back: the right
/// number of words, settings inside their range, known codes for enumerated settings.
/// Returns how many registers were read.
pub async fn read_every_register<T: Transport>(core: &mut Core<T>) -> usize {
    let device = core.device();
    let mut count = 0;
    for register in device.readable_registers() {
        let words = read_whole(core, register).await;
        if register.table == Table::Holding
            && register.access.writable()
            && sweepable(device, register)
        {
            if let Some((min, max)) = register.range {
                let value = Fixed::decode(register, &words).raw();
                assert!(
                    (min..=max).contains(&value),
                    "{} = {value}, outside {min}..={max}",
                    register.name
                );
            }
            if register.kind == ValueKind::Enum {
                let code = optobus_driver::raw_bits(register, &words);
                assert!(
                    register.codes.iter().any(|c| c.code == code),
                    "{} holds undefined code {code}",
                    register.name
                );
            }
        }
        count += 1;
    }
    count
}

/// The sweep every family's end-to-end suite starts with: [`read_every_register`], then
/// [`write_every_register`]. Returns how many writes were checked.
pub async fn sweep<T: Transport>(core: &mut Core<T>) -> usize {
    read_every_register(core).await;
    write_every_register(core).await
}

/// Writes valid values to every writable setting and reads each back (write-only registers
/// are only written). Returns how many writes were checked.
pub async fn write_every_register<T: Transport>(core: &mut Core<T>) -> usize {
    let device = core.device();
    let mut count = 0;
    for register in device.registers.iter() {
        if !register.access.writable() || !sweepable(device, register) {
            continue;
        }
        for words in valid_values(register) {
            core.write(register, &Words(words.clone()))
                .await
                .unwrap_or_else(|e| panic!("{} <- {words:04X?}: {e}", register.name));
            if register.readable() {
                let back = core
                    .read_words(register)
                    .await
                    .unwrap_or_else(|e| panic!("{}: {e}", register.name));
                assert_eq!(back, words, "{} read back", register.name);
            }
            count += 1;
        }
    }
    count
}
