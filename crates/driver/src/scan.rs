//! Scanning a line: which baud rate and slave address a device answers on, and which model
//! answers there (as [`identify`] finds it).

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
