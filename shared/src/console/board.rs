//! Which image answers the console: the rig's board, the emulator image or the virtual rig
//! (`id`'s `board=` field).

use super::token::Token;

/// Which image answers.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Board {
    /// The STM32F407 board of the rig.
    Rig,
    /// The emulator image on QEMU.
    Emulator,
    /// host-sim's virtual rig.
    Virtual,
}

impl Token for Board {
    const ALL: &'static [Board] = &[Board::Rig, Board::Emulator, Board::Virtual];
    fn token(self) -> &'static str {
        match self {
            Board::Rig => "rig",
            Board::Emulator => "emulator",
            Board::Virtual => "virtual",
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn board_names_read_back() {
        super::super::token::tests::names_read_back::<Board>();
        assert_eq!(Board::Emulator.token(), "emulator");
    }
}
