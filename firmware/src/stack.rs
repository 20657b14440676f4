//! Stack high-water mark, measured: the free stack is painted with a pattern at start-up and
//! the deepest overwritten word is found on demand (`diag stack_hwm_bytes`, the QEMU checks).
//!
//! With flip-link (the workspace's linker for the MCU) the stack sits at the bottom of RAM,
//! below the static data, and grows down toward the RAM's start: an overflow faults on the
//! address below RAM instead of overwriting statics. Without it the stack grows down from the
//! end of RAM toward the static data.

/// The pattern.
const PAINT: u32 = 0xC0FF_EE11;
/// Start of SRAM (memory.x).
const RAM_ORIGIN: usize = 0x2000_0000;

unsafe extern "C" {
    static _stack_start: u32;
}

/// The stack's region `[bottom, top)`.
fn region() -> (usize, usize) {
    // Only the symbol's address is taken.
    let top = core::ptr::addr_of!(_stack_start) as usize;
    let heap = cortex_m_rt::heap_start() as usize;
    // flip-link puts the static data (and the heap start after it) above the stack.
    let bottom = if heap >= top { RAM_ORIGIN } else { heap };
    (bottom, top)
}

/// Paints the unused stack (up to 256 bytes below the current stack pointer). Call once, early,
/// before interrupts are enabled.
pub fn paint() {
    let (bottom, _) = region();
    let sp = cortex_m::register::msp::read() as usize - 256;
    let mut p = bottom;
    while p < sp {
        // SAFETY: RAM between the stack's bottom and the live stack, not in use.
        unsafe { core::ptr::write_volatile(p as *mut u32, PAINT) };
        p += 4;
    }
}

/// Deepest stack use since [`paint`], bytes.
pub fn high_water_bytes() -> u32 {
    let (bottom, top) = region();
    let mut p = bottom;
    // SAFETY: reading the painted region.
    while p < top && unsafe { core::ptr::read_volatile(p as *const u32) } == PAINT {
        p += 4;
    }
    (top - p) as u32
}

/// The stack in use now (from its top to the stack pointer), bytes: what a call made here adds
/// to it is [`high_water_bytes`] after the call less this.
pub fn depth_bytes() -> u32 {
    let (_, top) = region();
    (top - cortex_m::register::msp::read() as usize) as u32
}

/// Size of the stack's region, bytes (RAM not taken by static data).
pub fn size_bytes() -> u32 {
    let (bottom, top) = region();
    (top - bottom) as u32
}
