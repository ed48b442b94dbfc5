//! The data-buffer download, once for every device whose spec has a `buffer:` section
//! ([`BufferInfo`]): buffering is started with a source and a count; later the buffer is
//! locked, read out a page at a time, and unlocked.

use std::fmt;

use optobus_device::{BufferInfo, CommandInfo, DeviceInfo, GroupInfo, RegisterInfo};
use optobus_transport::Transport;

use crate::convert::{Decode, Encode};
use crate::core::Core;
use crate::error::Error;

/// How far a download has got, passed to the progress callback after every page.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct DownloadProgress {
    /// Valid values received so far.
    pub received: usize,
    /// Values the buffer was set to report.
    pub expected: usize,
    /// Pages read so far.
    pub pages: usize,
}

/// A buffer's items, looked up in the device description.
struct Parts {
    info: &'static BufferInfo,
    count: &'static RegisterInfo,
    lock: (&'static CommandInfo, &'static RegisterInfo),
    unlock: (&'static CommandInfo, &'static RegisterInfo),
    page: &'static GroupInfo,
    read_count: &'static RegisterInfo,
    valid_count: &'static RegisterInfo,
    /// Every copy of the values register, in page order.
    values: Vec<&'static RegisterInfo>,
}

/// Refused: `device` describes no buffer, or one naming items it lacks.
fn no_buffer(name: &'static str) -> Error {
    Error::NotAllowed {
        register: name,
        what: "used as a data buffer (the device description has no such buffer)",
    }
}

impl Parts {
    fn of(device: &'static DeviceInfo) -> Result<Self, Error> {
        let info = device.buffer.ok_or_else(|| no_buffer(""))?;
        let register = |name: &'static str| device.register(name).ok_or_else(|| no_buffer(name));
        let command = |name: &'static str| {
            let command = device.command(name).ok_or_else(|| no_buffer(name))?;
            Ok::<_, Error>((command, register(command.register)?))
        };
        let values: Vec<_> = device.members(info.values).collect();
        if values.is_empty() {
            return Err(no_buffer(info.values));
        }
        Ok(Self {
            info,
            count: register(info.count)?,
            lock: command(info.lock)?,
            unlock: command(info.unlock)?,
            page: device
                .group(info.page)
                .ok_or_else(|| no_buffer(info.page))?,
            read_count: register(info.read_count)?,
            valid_count: register(info.valid_count)?,
            values,
        })
    }

    /// Refuses a count above the values that may be read out.
    fn check_count(&self, count: u32) -> Result<(), Error> {
        if count > self.info.most {
            return Err(Error::OutOfRange {
                register: self.count.name,
                raw: i64::from(count),
                min: 0,
                max: i64::from(self.info.most),
                scale: None,
                unit: None,
            });
        }
        Ok(())
    }
}

impl<T: Transport> Core<T> {
    /// The device's data buffer, if its spec describes one.
    pub fn buffer(&self) -> Option<&'static BufferInfo> {
        self.device().buffer
    }

    /// Starts buffering `count` values of `source` (writes the source register, if the
    /// buffer has one, and the count, then unlocks): 0 turns buffering off. A count above
    /// the buffer's `most` is refused with [`Error::OutOfRange`], and every value is checked,
    /// before anything is sent.
    pub async fn start_buffering(
        &mut self,
        source: Option<&dyn Encode>,
        count: u32,
    ) -> Result<(), Error> {
        let parts = Parts::of(self.device())?;
        parts.check_count(count)?;
        let source = match (parts.info.source, source) {
            (Some(name), Some(source)) => {
                let register = self
                    .device()
                    .register(name)
                    .ok_or_else(|| no_buffer(name))?;
                Some((register, source.encode(register)?))
            }
            _ => None,
        };
        let count_words = count.encode(parts.count)?;
        if let Some((register, words)) = source {
            self.write_words(register, &words).await?;
        }
        self.write_words(parts.count, &count_words).await?;
        let (command, register) = parts.unlock;
        self.run(command, register).await
    }

    /// Reads the buffer out: locks it, reads pages until the count it was set to is reached
    /// or a page carries no valid value, and unlocks it again, also when a read fails. Values
    /// come oldest first, each decoded as `V` (`Option<_>` gives `None` for a value the
    /// device marks invalid); values past a page's valid count are ignored.
    ///
    /// Reading a page turns it, so a page read is never retried, and at most the pages the
    /// count needs are read. Every page's read count (the device's count of values handed
    /// out since the lock) is checked against the values received: a page lost on the way
    /// fails the download with [`Error::OutOfStep`] instead of returning fewer values.
    pub async fn download_buffer<V: Decode + fmt::Debug>(
        &mut self,
        mut progress: impl FnMut(DownloadProgress),
    ) -> Result<Vec<V>, Error> {
        let parts = Parts::of(self.device())?;
        let count: u32 = self.read(parts.count).await?;
        let expected = usize::try_from(count.min(parts.info.most)).unwrap_or(usize::MAX);
        let (command, register) = parts.lock;
        self.run(command, register).await?;
        let result = self.read_pages(&parts, expected, &mut progress).await;
        let (command, register) = parts.unlock;
        let unlocked = self.run(command, register).await;
        let values = result?;
        unlocked?;
        Ok(values)
    }

    async fn read_pages<V: Decode + fmt::Debug>(
        &mut self,
        parts: &Parts,
        expected: usize,
        progress: &mut impl FnMut(DownloadProgress),
    ) -> Result<Vec<V>, Error> {
        let page_values = parts.values.len();
        let mut values = Vec::with_capacity(expected);
        // Values the device handed out in the pages we received.
        let mut handed_out = 0u64;
        // Each page must be read whole, or values are lost; a device that keeps reporting
        // values is stopped after the pages `expected` needs.
        let max_pages = expected.div_ceil(page_values);
        for pages in 1..=max_pages {
            let page = self.read_declared_group(parts.page).await?;
            let read_count: u32 = page.get(parts.read_count);
            let valid_count: u32 = page.get(parts.valid_count);
            let valid_in_page = usize::try_from(valid_count)
                .unwrap_or(usize::MAX)
                .min(page_values);
            handed_out += valid_in_page as u64;
            if u64::from(read_count) != handed_out {
                return Err(Error::OutOfStep {
                    what: "the buffer download",
                    received: handed_out,
                    reported: u64::from(read_count),
                });
            }
            let valid = valid_in_page.min(expected - values.len());
            values.extend(parts.values[..valid].iter().map(|r| page.get::<V>(r)));
            progress(DownloadProgress {
                received: values.len(),
                expected,
                pages,
            });
            if valid == 0 || values.len() >= expected {
                break;
            }
        }
        Ok(values)
    }
}
