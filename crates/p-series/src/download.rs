//! The buffered-data download of manual section 5.4 and appendix 3, on top of the generated
//! API: buffering is started with a data type and a report count; later the buffer is locked,
//! read in pages of 60 values (122 registers from `buffer_read_count`), and unlocked.

use optobus_driver::units::Millimetres;
use optobus_driver::{Error, Transport};

use crate::{BufferPage, MeasurementSource, PSeries};

/// Most values the manual allows to be read out of the buffer (appendix 3).
pub const MAX_DOWNLOAD: u16 = 2500;

/// Values one page carries.
pub const PAGE_VALUES: usize = 60;

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

impl<T: Transport> PSeries<T> {
    /// Starts buffering `count` values of `source` (5.4 "开启缓存数据功能": data type, report
    /// count, unlocked). `count` is at most [`MAX_DOWNLOAD`]; 0 turns buffering off.
    pub async fn start_buffering(
        &mut self,
        source: MeasurementSource,
        count: u16,
    ) -> Result<(), Error> {
        if count > MAX_DOWNLOAD {
            return Err(Error::OutOfRange {
                register: "buffer_report_count",
                raw: i64::from(count),
                min: 0,
                max: i64::from(MAX_DOWNLOAD),
                scale: None,
            });
        }
        self.set_buffer_data_type(source).await?;
        self.set_buffer_report_count(count).await?;
        self.unlock_buffer().await
    }

    /// Reads the buffer out (5.4 "缓存数据读取操作"): locks it, reads pages until the report
    /// count is reached or a page carries no valid value, and unlocks it again, also when a
    /// read fails. Values come oldest first; `None` is a reading the sensor marked invalid.
    ///
    /// Reading a page turns it, so a page read is never retried, and every page's
    /// `buffer_read_count` (the device's count of values handed out since the lock) is checked
    /// against the values received: a page lost on the way fails the download with
    /// [`Error::OutOfStep`] instead of returning fewer values.
    pub async fn download_buffer(
        &mut self,
        mut progress: impl FnMut(DownloadProgress),
    ) -> Result<Vec<Option<Millimetres>>, Error> {
        let expected = usize::from(self.buffer_report_count().await?.min(MAX_DOWNLOAD));
        self.lock_buffer().await?;
        let result = self.read_pages(expected, &mut progress).await;
        let unlocked = self.unlock_buffer().await;
        let values = result?;
        unlocked?;
        Ok(values)
    }

    async fn read_pages(
        &mut self,
        expected: usize,
        progress: &mut impl FnMut(DownloadProgress),
    ) -> Result<Vec<Option<Millimetres>>, Error> {
        let mut values = Vec::with_capacity(expected);
        // Values the device handed out in the pages we received.
        let mut handed_out = 0u64;
        // Each page must be read whole, or values are lost (appendix 3); a device that keeps
        // reporting values is stopped after the pages `expected` needs.
        let max_pages = expected.div_ceil(PAGE_VALUES);
        for pages in 1..=max_pages {
            let BufferPage {
                buffer_read_count,
                buffer_valid_count,
                buffered_value,
            } = self.read_buffer_page().await?;
            handed_out += u64::from(buffer_valid_count.min(PAGE_VALUES as u16));
            if u64::from(buffer_read_count) != handed_out {
                return Err(Error::OutOfStep {
                    what: "the buffer download",
                    received: handed_out,
                    reported: u64::from(buffer_read_count),
                });
            }
            let valid = usize::from(buffer_valid_count)
                .min(PAGE_VALUES)
                .min(expected - values.len());
            values.extend_from_slice(&buffered_value[..valid]);
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
