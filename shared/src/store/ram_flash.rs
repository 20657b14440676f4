//! A NOR flash in RAM ([`RamFlash`]): the store's flash for the emulator image (QEMU's board
//! emulates no flash controller), the virtual rig and the tests, with the geometry of the rig
//! board's store (pages of [`PAGE_BYTES`], words of [`WORD_BYTES`]) and NOR's rules: an erase
//! sets bytes to `0xFF`, a write can only clear bits (the result is the AND of old and new). A
//! power cut can be armed ([`RamFlash::cut_power_after`]): after that many steps (a word written,
//! a kilobyte erased) the operation stops part-way and every later one fails, as on a board
//! whose supply failed mid-save.

use embedded_storage_async::nor_flash::{
    ErrorType, MultiwriteNorFlash, NorFlash, NorFlashError, NorFlashErrorKind, ReadNorFlash,
};

/// A page (erase unit): the rig board's 16 KiB sectors.
pub const PAGE_BYTES: usize = 16 * 1024;
/// A word (write unit): the rig board programs 32-bit words (x32 parallelism).
pub const WORD_BYTES: usize = 4;
/// An erase's step for power cuts: a kilobyte.
const ERASE_STEP: usize = 1024;

/// Why a RAM flash operation failed.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum RamFlashError {
    /// Outside the flash or not aligned to its read, write or erase unit.
    OutOfBounds,
    /// The armed power cut happened (this operation stopped part-way, or came after).
    PowerCut,
}

impl NorFlashError for RamFlashError {
    fn kind(&self) -> NorFlashErrorKind {
        match self {
            RamFlashError::OutOfBounds => NorFlashErrorKind::OutOfBounds,
            RamFlashError::PowerCut => NorFlashErrorKind::Other,
        }
    }
}

/// NOR flash over bytes `B` (a slice, a `Vec`: its length a multiple of [`PAGE_BYTES`]).
#[derive(Debug)]
pub struct RamFlash<B> {
    bytes: B,
    /// Steps left before the power cut (`None`: no cut armed).
    power_left: Option<u64>,
    /// Steps made (words written, kilobytes erased).
    steps: u64,
    /// Pages erased whole.
    pages_erased: u64,
}

impl<B: AsRef<[u8]> + AsMut<[u8]>> RamFlash<B> {
    /// The flash over `bytes` as they are (the caller erases a new one: [`RamFlash::erased`]).
    pub fn new(bytes: B) -> Self {
        RamFlash {
            bytes,
            power_left: None,
            steps: 0,
            pages_erased: 0,
        }
    }

    /// The flash over `bytes`, erased.
    pub fn erased(mut bytes: B) -> Self {
        bytes.as_mut().fill(0xff);
        RamFlash::new(bytes)
    }

    /// The power fails after `steps` more steps.
    pub fn cut_power_after(&mut self, steps: u64) {
        self.power_left = Some(steps);
    }

    /// Steps made so far (words written, kilobytes erased).
    pub fn steps(&self) -> u64 {
        self.steps
    }

    /// Pages erased whole so far.
    pub fn pages_erased(&self) -> u64 {
        self.pages_erased
    }

    /// The bytes (to flip one, as a worn or disturbed cell would).
    pub fn bytes_mut(&mut self) -> &mut [u8] {
        self.bytes.as_mut()
    }

    /// One more step, unless the power is cut.
    fn step(&mut self) -> Result<(), RamFlashError> {
        match &mut self.power_left {
            Some(0) => Err(RamFlashError::PowerCut),
            Some(n) => {
                *n -= 1;
                self.steps += 1;
                Ok(())
            }
            None => {
                self.steps += 1;
                Ok(())
            }
        }
    }

    fn range(
        &self,
        offset: u32,
        len: usize,
        unit: usize,
    ) -> Result<core::ops::Range<usize>, RamFlashError> {
        let start = offset as usize;
        let end = start.checked_add(len).ok_or(RamFlashError::OutOfBounds)?;
        if end > self.bytes.as_ref().len()
            || !start.is_multiple_of(unit)
            || !len.is_multiple_of(unit)
        {
            return Err(RamFlashError::OutOfBounds);
        }
        Ok(start..end)
    }
}

impl<B> ErrorType for RamFlash<B> {
    type Error = RamFlashError;
}

impl<B: AsRef<[u8]> + AsMut<[u8]>> ReadNorFlash for RamFlash<B> {
    const READ_SIZE: usize = 1;

    async fn read(&mut self, offset: u32, bytes: &mut [u8]) -> Result<(), RamFlashError> {
        let r = self.range(offset, bytes.len(), 1)?;
        bytes.copy_from_slice(&self.bytes.as_ref()[r]);
        Ok(())
    }

    fn capacity(&self) -> usize {
        self.bytes.as_ref().len()
    }
}

impl<B: AsRef<[u8]> + AsMut<[u8]>> NorFlash for RamFlash<B> {
    const WRITE_SIZE: usize = WORD_BYTES;
    const ERASE_SIZE: usize = PAGE_BYTES;

    async fn erase(&mut self, from: u32, to: u32) -> Result<(), RamFlashError> {
        let len = (to as usize)
            .checked_sub(from as usize)
            .ok_or(RamFlashError::OutOfBounds)?;
        let r = self.range(from, len, PAGE_BYTES)?;
        let pages = (r.len() / PAGE_BYTES) as u64;
        for chunk in r.step_by(ERASE_STEP) {
            self.step()?;
            self.bytes.as_mut()[chunk..chunk + ERASE_STEP].fill(0xff);
        }
        self.pages_erased += pages;
        Ok(())
    }

    async fn write(&mut self, offset: u32, bytes: &[u8]) -> Result<(), RamFlashError> {
        let r = self.range(offset, bytes.len(), WORD_BYTES)?;
        for (k, src) in bytes.chunks_exact(WORD_BYTES).enumerate() {
            self.step()?;
            let at = r.start + k * WORD_BYTES;
            for (d, s) in self.bytes.as_mut()[at..at + WORD_BYTES].iter_mut().zip(src) {
                *d &= *s;
            }
        }
        Ok(())
    }
}

/// NOR rules: a second write of a word ANDs it (what the rig board's flash does too, RM0090
/// §3.6.4: bits go from 1 to 0 without an erase).
impl<B: AsRef<[u8]> + AsMut<[u8]>> MultiwriteNorFlash for RamFlash<B> {}
