//! Scanning a line: which baud rate and slave address a device answers on, and which model
//! answers there (as [`identify`] finds it); and the lists of slave addresses and baud rates
//! a scan tries, read from text (`1-10,247`, `9600,115200`) with a typed refusal each.

use std::fmt;
use std::future::Future;

use optobus_device::DeviceInfo;

use crate::identify::{identify, ConnectAs, Identification};
use crate::{Core, Error, Transport};

/// Opens a link to the line at a baud rate, framed as a model expects it: what a scan needs.
pub trait ConnectAt {
    /// The link.
    type Link: Transport;
    /// Why no link could be opened (the port cannot be reached), or a driver error: the
    /// scan stops.
    type Error: From<Error>;

    /// A link at `baud`, framed for `model`.
    fn connect_at(
        &mut self,
        model: &'static DeviceInfo,
        baud: u32,
    ) -> impl Future<Output = Result<Self::Link, Self::Error>>;
}

/// A device a scan found.
#[derive(Clone, Debug)]
pub struct Found {
    /// The baud rate it answered at.
    pub baud: u32,
    /// Its slave address.
    pub slave: u8,
    /// Which model it is, asked at that address.
    pub identification: Identification,
}

/// What a scan is doing, as it goes.
#[derive(Debug)]
pub enum ScanStep<'a> {
    /// Probing `slave` at `baud`.
    Probing {
        /// The baud rate.
        baud: u32,
        /// The slave address.
        slave: u8,
    },
    /// A device answered and was identified.
    Found(&'a Found),
}

/// Probes every slave of `slaves` at each of `bauds`, framed as `device`; where anything
/// answers (an exception too: something lives there), identifies it among `candidates` on
/// new links, then goes on only if `all`. `step` is told each probe and each find. A port
/// that cannot be opened stops the scan.
pub async fn scan<C: ConnectAt>(
    connect: &mut C,
    device: &'static DeviceInfo,
    bauds: &[u32],
    slaves: &[u8],
    candidates: &[&'static DeviceInfo],
    all: bool,
    mut step: impl FnMut(ScanStep<'_>),
) -> Result<Vec<Found>, C::Error> {
    let mut found = Vec::new();
    for &baud in bauds {
        let mut prober = None;
        for &slave in slaves {
            step(ScanStep::Probing { baud, slave });
            let core = match &mut prober {
                Some(core) => core,
                None => prober.insert(Core::with_default_slave(
                    connect.connect_at(device, baud).await?,
                    device,
                )),
            };
            if !core.answers_at(slave).await? {
                continue;
            }
            // The port is opened anew for each model identify tries.
            prober = None;
            let identification =
                identify(&mut AtBaud { connect, baud }, candidates, Some(slave)).await?;
            found.push(Found {
                baud,
                slave,
                identification,
            });
            if let Some(last) = found.last() {
                step(ScanStep::Found(last));
            }
            if !all {
                return Ok(found);
            }
        }
    }
    Ok(found)
}

/// A [`ConnectAt`] held at one baud rate, for [`identify`].
struct AtBaud<'c, C> {
    connect: &'c mut C,
    baud: u32,
}

impl<C: ConnectAt> ConnectAs for AtBaud<'_, C> {
    type Link = C::Link;
    type Error = C::Error;

    async fn connect_as(&mut self, model: &'static DeviceInfo) -> Result<C::Link, C::Error> {
        self.connect.connect_at(model, self.baud).await
    }
}

/// The first and last address a device can have on a line: 0 is the broadcast address, and
/// Modbus reserves 248 to 255.
pub const DEVICE_ADDRESSES: (u8, u8) = (1, 247);

/// The lowest and highest baud rate a serial port can be asked for.
pub const BAUD_RATES: (u32, u32) = (50, 4_000_000);

/// Why a list of slave addresses was refused, said with the `option` (or key) it was given
/// as: `Display` is the message, [`hint`](Self::hint) what to write instead.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum SlaveListError {
    /// Nothing at all.
    Empty {
        /// The option (`--slaves`).
        option: &'static str,
    },
    /// An empty item between commas.
    EmptyItem {
        /// The option.
        option: &'static str,
        /// The whole list.
        text: String,
    },
    /// An item that is neither an address nor a range of two.
    NotAnAddress {
        /// The option.
        option: &'static str,
        /// The item.
        item: String,
    },
    /// A number outside [`DEVICE_ADDRESSES`].
    NoDeviceAddress {
        /// The option.
        option: &'static str,
        /// The number.
        number: u32,
    },
    /// A range whose first address is above its last.
    Backwards {
        /// The option.
        option: &'static str,
        /// The range as written.
        item: String,
        /// Its first address.
        from: u8,
        /// Its last address.
        to: u8,
    },
    /// An address listed twice.
    Twice {
        /// The option.
        option: &'static str,
        /// The address.
        slave: u8,
        /// The item that lists it again.
        item: String,
    },
}

impl SlaveListError {
    /// What to write instead, where an example helps.
    pub fn hint(&self) -> Option<String> {
        match self {
            Self::Empty { option }
            | Self::EmptyItem { option, .. }
            | Self::NotAnAddress { option, .. } => Some(format!("e.g. {option} 1-10,247")),
            Self::NoDeviceAddress { .. } => {
                Some("0 is the broadcast address, 248 to 255 are reserved".to_owned())
            }
            Self::Backwards { from, to, .. } => Some(format!("write {to}-{from}")),
            Self::Twice { .. } => None,
        }
    }
}

impl fmt::Display for SlaveListError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let (first, last) = DEVICE_ADDRESSES;
        match self {
            Self::Empty { option } => write!(f, "{option} is empty"),
            Self::EmptyItem { option, text } => write!(f, "{option} `{text}` has an empty item"),
            Self::NotAnAddress { option, item } => {
                write!(f, "{option}: `{item}` is not an address or a range")
            }
            Self::NoDeviceAddress { option, number } => write!(
                f,
                "{option}: {number} is no device address: scan {first} to {last}"
            ),
            Self::Backwards { option, item, .. } => {
                write!(f, "{option}: the range `{item}` runs backwards")
            }
            Self::Twice {
                option,
                slave,
                item,
            } => write!(f, "{option} lists address {slave} twice (in `{item}`)"),
        }
    }
}

impl std::error::Error for SlaveListError {}

/// The slave addresses `text` lists, given as `option`: addresses and ascending ranges
/// (`1-10,247`), each a device address ([`DEVICE_ADDRESSES`]), none twice, not empty; in the
/// order listed.
pub fn parse_slaves(text: &str, option: &'static str) -> Result<Vec<u8>, SlaveListError> {
    let (first, last) = DEVICE_ADDRESSES;
    let address = |item: &str, part: &str| -> Result<u8, SlaveListError> {
        let number: u32 = part
            .trim()
            .parse()
            .map_err(|_| SlaveListError::NotAnAddress {
                option,
                item: item.to_owned(),
            })?;
        u8::try_from(number)
            .ok()
            .filter(|n| (first..=last).contains(n))
            .ok_or(SlaveListError::NoDeviceAddress { option, number })
    };
    if text.trim().is_empty() {
        return Err(SlaveListError::Empty { option });
    }
    let mut slaves: Vec<u8> = Vec::new();
    for item in text.split(',').map(str::trim) {
        if item.is_empty() {
            let text = text.to_owned();
            return Err(SlaveListError::EmptyItem { option, text });
        }
        let (from, to) = item.split_once('-').unwrap_or((item, item));
        let (from, to) = (address(item, from)?, address(item, to)?);
        let item = item.to_owned();
        if from > to {
            return Err(SlaveListError::Backwards {
                option,
                item,
                from,
                to,
            });
        }
        for slave in from..=to {
            if slaves.contains(&slave) {
                return Err(SlaveListError::Twice {
                    option,
                    slave,
                    item,
                });
            }
            slaves.push(slave);
        }
    }
    Ok(slaves)
}

/// Why a list of baud rates was refused, said with the `option` it was given as; `E` is the
/// refusal of the caller's check of each rate.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum BaudListError<E> {
    /// An empty item between commas (or nothing at all).
    EmptyItem {
        /// The option (`--bauds`).
        option: &'static str,
        /// The whole list.
        text: String,
    },
    /// An item that is no number.
    NotABaud {
        /// The option.
        option: &'static str,
        /// The item.
        item: String,
    },
    /// A rate listed twice.
    Twice {
        /// The option.
        option: &'static str,
        /// The rate.
        baud: u32,
    },
    /// A rate the caller's check refused.
    Refused(E),
}

impl<E> BaudListError<E> {
    /// What to write instead, where an example helps.
    pub fn hint(&self) -> Option<String> {
        match self {
            Self::EmptyItem { option, .. } => Some(format!("e.g. {option} 9600,115200")),
            _ => None,
        }
    }
}

impl<E: fmt::Display> fmt::Display for BaudListError<E> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::EmptyItem { option, text } => write!(f, "{option} `{text}` has an empty item"),
            Self::NotABaud { option, item } => write!(f, "{option}: `{item}` is not a baud rate"),
            Self::Twice { option, baud } => write!(f, "{option} lists {baud} twice"),
            Self::Refused(error) => error.fmt(f),
        }
    }
}

impl<E: fmt::Debug + fmt::Display> std::error::Error for BaudListError<E> {}

/// The baud rates `text` lists, given as `option` (`9600,115200`): each a number that `check`
/// passes, no empty item, none twice; in the order listed.
pub fn parse_bauds<E>(
    text: &str,
    option: &'static str,
    mut check: impl FnMut(u32) -> Result<(), E>,
) -> Result<Vec<u32>, BaudListError<E>> {
    let mut bauds = Vec::new();
    for item in text.split(',').map(str::trim) {
        if item.is_empty() {
            let text = text.to_owned();
            return Err(BaudListError::EmptyItem { option, text });
        }
        let baud: u32 = item.parse().map_err(|_| BaudListError::NotABaud {
            option,
            item: item.to_owned(),
        })?;
        check(baud).map_err(BaudListError::Refused)?;
        if bauds.contains(&baud) {
            return Err(BaudListError::Twice { option, baud });
        }
        bauds.push(baud);
    }
    Ok(bauds)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn slaves(text: &str) -> Result<Vec<u8>, String> {
        parse_slaves(text, "--slaves").map_err(|e| match e.hint() {
            Some(hint) => format!("{e} ({hint})"),
            None => e.to_string(),
        })
    }

    #[test]
    fn a_slave_list_takes_addresses_and_ascending_ranges_in_the_order_listed() {
        assert_eq!(slaves("3, 1-2,247"), Ok(vec![3, 1, 2, 247]));
        assert_eq!(slaves("5-5"), Ok(vec![5]));
    }

    #[test]
    fn a_slave_list_is_refused_with_the_option_and_what_to_write() {
        let example = "(e.g. --slaves 1-10,247)";
        let cases = [
            (" ", format!("--slaves is empty {example}")),
            ("1,,2", format!("--slaves `1,,2` has an empty item {example}")),
            ("1-x", format!("--slaves: `1-x` is not an address or a range {example}")),
            (
                "0-3",
                "--slaves: 0 is no device address: scan 1 to 247 (0 is the broadcast address, \
                 248 to 255 are reserved)"
                    .to_owned(),
            ),
            ("248", "--slaves: 248 is no device address: scan 1 to 247 (0 is the broadcast address, 248 to 255 are reserved)".to_owned()),
            ("9-3", "--slaves: the range `9-3` runs backwards (write 3-9)".to_owned()),
            ("1-3,2", "--slaves lists address 2 twice (in `2`)".to_owned()),
        ];
        for (text, expected) in cases {
            assert_eq!(slaves(text), Err(expected), "{text}");
        }
    }

    #[test]
    fn a_baud_list_is_checked_rate_by_rate_and_refused_with_the_option() {
        let under_a_million = |baud: u32| match baud {
            0..=999_999 => Ok(()),
            _ => Err(format!("{baud} is too fast")),
        };
        let bauds = |text: &str| {
            parse_bauds(text, "--bauds", under_a_million).map_err(|e| (e.to_string(), e.hint()))
        };
        assert_eq!(bauds("115200, 9600"), Ok(vec![115_200, 9600]));
        let example = Some("e.g. --bauds 9600,115200".to_owned());
        assert_eq!(
            bauds("9600,"),
            Err(("--bauds `9600,` has an empty item".to_owned(), example))
        );
        assert_eq!(
            bauds("fast"),
            Err(("--bauds: `fast` is not a baud rate".to_owned(), None))
        );
        assert_eq!(
            bauds("9600,2000000"),
            Err(("2000000 is too fast".to_owned(), None))
        );
        assert_eq!(
            bauds("9600,9600"),
            Err(("--bauds lists 9600 twice".to_owned(), None))
        );
    }
}
