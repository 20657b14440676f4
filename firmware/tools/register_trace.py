#!/usr/bin/env python3
"""The rig image's register writes, recorded: runs the rig image (`firmware`, the one QEMU cannot
run: no RCC, DMA, DAC or triggered ADC there) in unicorn, an instruction-level emulator of the
Cortex-M4, from its reset handler through `init` to its idle loop, then feeds it interrupts as
the hardware would raise them, and prints every access to a peripheral register.

Usage: register_trace.py ELF [--out FILE]        (pip install unicorn pyelftools)

Exit status 0 when the scenario ran to its end; 2 when unicorn or pyelftools is missing (the
message says so); 1 on any other failure (the trace so far is printed, then the error).

What is modelled (the rest of the address space is plain memory: a register reads what was
last written, from its reset value):
- RCC: HSIRDY, HSERDY, PLLRDY, PLLI2SRDY read as set when their oscillator is on, SWS mirrors
  SW, LSIRDY is set (RM0090 §7.3.1, §7.3.3, §7.3.21); the flash's VREFINT calibration word
  (0x1FFF_7A2A) holds 1500.
- ADC1, ADC2: ADC_SR's flags are rc_w0 (a written 0 clears, a 1 leaves, §13.13.1); a software
  start (CR2.SWSTART) ends at once with EOC and a result of 1500 (the HAL's calibration), and
  SWSTART reads 0 again (§13.13.3); a read of ADC_DR clears EOC.
- DMA2: LISR's flags are cleared by writes of 1 to LIFCR (§10.5.1, §10.5.3).
- USART2: TXE and TC always set; RXNE while received bytes wait; DR reads them in turn, DR
  writes are the board's output (collected into reply lines).
- NVIC: ISER/ICER, ISPR/ICPR and STIR as enabled and pending sets; IPR bytes as written. An
  interrupt is delivered when it is enabled and pending (set in ISPR, or its peripheral's flag
  and enable: ADC EOC with EOCIE, USART2 TXE with TXEIE or RXNE with RXNEIE, DMA2 stream 2's
  TC/TE/DME flags with their enables), highest NVIC priority first; its handler runs to its end
  with the interrupted registers restored after; it is interrupted only as a flash operation
  ends (below), by what beats its priority (BASEPRI and PRIMASK counted). Interrupts at the
  lowest priority (0xF0: RTIC's priority 1, the model task's 46 M instructions) are not
  delivered. SysTick is taken only in `Rig.systick` (the scenario's `reset`): COUNTFLAG reads
  1 once after each 1 ms wrap, ICSR.PENDSTSET pends it; an AIRCR write with VECTKEY and
  SYSRESETREQ (a `system-reset` marker) ends the run, and the scenario powers up again.
- Time: TIM5_CNT (the µs clock) is set by the scenario and moved on by a flash operation's
  stall; nothing else counts.
- The flash (RM0090 §3.3–3.9): sectors 1–2 (the settings store, 0x0800_4000, 32 KiB) hold
  what the runs of one scenario programmed (erased: 0xFF); every other sector is
  write-protected here. FLASH_KEYR: KEY1 then KEY2 clear FLASH_CR.LOCK; a wrong key or a key
  while unlocked locks it until reset (a `flash-error` marker). FLASH_CR written only
  unlocked. A CPU store into the flash programs (bits only cleared) with PG set, the access
  size PSIZE says, inside one 128-bit row, in the store (else PGSERR, PGPERR, PGAERR, WRPERR);
  SER + SNB + STRT erases a store sector (another sector or MER: WRPERR). An operation shows
  BSY for 3 FLASH_SR reads; as BSY clears, the CPU (stalled on the flash meanwhile) goes on
  100 µs (a word) or 500 ms (an erase) later: TIM5 moves on, ADC1 has converted (an overrun if
  more than once), and the sampling interrupt preempts the code that stalled at the next
  block. FLASH_SR's error flags are rc_w1. A board's option bytes may protect sectors
  (`protected`: WRPERR).
- Unicorn quirks worked around: a stop asked for from a memory hook inside an IT block is
  lost (the stop waits for the next block), and a hook on an instruction inside an IT block
  leaves its IT state in the CPU, which would make the next block looked up conditional (the
  IT bits are cleared after each hook).

The trace, one line per event:
  W <seq> <addr> <size> <value> <pc>     a write to a peripheral or system register, or a
                                         CPU store into the flash (0x08xx_xxxx: programming)
  B <seq> <addr> <bit> <value> <pc>      the bit a bit-band alias write (the W before it) sets
                                         or clears in the peripheral register at <addr>
  R <seq> <addr> <size> <value> <pc>     a read, with the value the image got
  M <seq> <kind> [text]                  a marker: power-up, phase <name>, interrupts-on,
                                         idle, irq <n> <handler>, reply <text>,
                                         stream-disabled (a DMA block not transferred),
                                         flash-erase <sector>, flash-error <what>, done
Addresses and values are hexadecimal.

The scenario (the phases, in order):
  boot          reset → `init` → interrupts on → pending interrupts delivered → idle
  sample        two ADC1 ends of conversion, 100 µs apart (the sampling task, the DAC write)
  capture-arm   `capture arm 1 0.5` on the console (the capture's stream and TIM3 started)
  console-armed `status` while the capture records (nothing may restart TIM3)
  capture-block a full DMA block (TCIF2, CT switched) 650 µs after the start, then `capture`
  capture-error a transfer error (TEIF2, the stream disabled, ADC2 overrun) 1 ms later, then
                `capture`
  capture-rearm `capture stop`, `capture arm 1 0.5` (the next capture's stream re-armed)
  capture-stopped `capture stop`, a full block (the capture task stops TIM3), then another
                (a block completed as it stopped: its flag must be cleared, or the interrupt
                comes again for ever)
  save          `rig beam-150`, `gap 1.5`, `save` (words programmed in sector 1 while the
                sampling goes on), `status`
  revert        `revert` (the settings read back from the flash)
  adc-overrun   an ADC1 end of conversion with OVR set (the sampling task's overrun path)
Then the board powered up again on the same flash:
  reboot        start-up loads the stored settings; `id`, `store`
  reset         `reset`: its reply, SysTick ticks until the image writes AIRCR.SYSRESETREQ
  after-reset   the board restarted on the same flash; `id`
And on a store cut as it moved to its other sector (sector 2 full and closed, sector 1 just
opened):
  cut-boot      start-up loads it; `id`
  cut-save      `save`: both sectors erased (500 ms stalls: ADC1 overruns, no fault), `status`
  cut-overrun   an ADC1 overrun after the save: a fault (the deadline checks are back)
And with the store's sectors write-protected by the option bytes:
  wrp-boot, wrp-save   `gap 2`, `save`: WRPERR on the first word, the save refused; `status`
"""
import argparse
import struct
import sys

try:
    from elftools.elf.elffile import ELFFile
    from unicorn import (UC_ARCH_ARM, UC_HOOK_BLOCK, UC_HOOK_CODE, UC_HOOK_MEM_READ, UC_HOOK_MEM_WRITE,
                         UC_HOOK_MEM_WRITE_PROT, UC_MODE_MCLASS, UC_MODE_THUMB, UC_PROT_EXEC,
                         UC_PROT_READ, Uc, UcError)
    from unicorn.arm_const import (UC_ARM_REG_BASEPRI, UC_ARM_REG_LR, UC_ARM_REG_PC,
                                   UC_ARM_REG_PRIMASK, UC_ARM_REG_SP, UC_ARM_REG_XPSR,
                                   UC_CPU_ARM_CORTEX_M4)
except ImportError as e:  # pragma: no cover
    print(f"register_trace.py needs python3 with unicorn and pyelftools "
          f"(pip install unicorn pyelftools): {e}", file=sys.stderr)
    sys.exit(2)

# Memory map (RM0090 §2.3, Table 1; PM0214 §4.1 for the system control space).
FLASH = (0x0800_0000, 0x10_0000)
SYSMEM = (0x1FFF_0000, 0x1_0000)
CCM = (0x1000_0000, 0x1_0000)
SRAM = (0x2000_0000, 0x2_0000)
PERIPH = (0x4000_0000, 0x2000_0000)
SCS = (0xE000_0000, 0x10_0000)
BITBAND = (0x4200_0000, 0x0200_0000)
# Where a handler "returns" to: the last word of flash, hooked.
RETURN_TRAP = FLASH[0] + FLASH[1] - 0x10
# The flash's sectors (RM0090 §3.3, Table 5: one bank of 1 MiB): 4 × 16 KiB, 64 KiB, 7 × 128 KiB.
SECTOR_SIZES = [0x4000] * 4 + [0x1_0000] + [0x2_0000] * 7
SECTOR_BASES = [FLASH[0] + sum(SECTOR_SIZES[:n]) for n in range(len(SECTOR_SIZES))]
# The settings store: sectors 1 and 2 (the image's `memory.x` keeps them free of code), writable
# here; every other sector is modelled write-protected (see the module's description).
STORE_SECTORS = (1, 2)
STORE = (SECTOR_BASES[1], SECTOR_SIZES[1] + SECTOR_SIZES[2])

RCC = 0x4002_3800
RCC_CR, RCC_PLLCFGR, RCC_CFGR, RCC_CSR = RCC, RCC + 0x04, RCC + 0x08, RCC + 0x74
ADC1, ADC2 = 0x4001_2000, 0x4001_2100
ADC_SR, ADC_CR1, ADC_CR2, ADC_DR = 0x00, 0x04, 0x08, 0x4C
DMA2 = 0x4002_6400
DMA_LISR, DMA_LIFCR = DMA2 + 0x00, DMA2 + 0x08
S2CR, S2NDTR, S2M0AR, S2M1AR = DMA2 + 0x40, DMA2 + 0x44, DMA2 + 0x4C, DMA2 + 0x50
USART2 = 0x4000_4400
USART_SR, USART_DR, USART_CR1 = USART2, USART2 + 0x04, USART2 + 0x0C
TIM5_CNT = 0x4000_0C24
GPIOA = 0x4002_0000
IWDG_RLR = 0x4000_3008
DMA2_S2FCR = DMA2 + 0x54
VREFINT_CAL = 0x1FFF_7A2A
TIM2_CR1 = 0x4000_0000
# The flash interface (RM0090 §3.9): ACR §3.9.1, KEYR §3.9.2, SR §3.9.4, CR §3.9.5.
FLASH_IF = 0x4002_3C00
FLASH_ACR, FLASH_KEYR, FLASH_SR, FLASH_CR = FLASH_IF, FLASH_IF + 0x04, FLASH_IF + 0x0C, FLASH_IF + 0x10
FLASH_KEYS = (0x4567_0123, 0xCDEF_89AB)
# FLASH_SR: EOP 0, OPERR 1, WRPERR 4, PGAERR 5, PGPERR 6, PGSERR 7 (rc_w1), BSY 16.
SR_EOP, SR_WRPERR, SR_PGAERR, SR_PGPERR, SR_PGSERR, SR_BSY = 1, 1 << 4, 1 << 5, 1 << 6, 1 << 7, 1 << 16
SR_RC_W1 = 0b1111_0011
SR_NAMES = {SR_WRPERR: "WRPERR", SR_PGAERR: "PGAERR", SR_PGPERR: "PGPERR", SR_PGSERR: "PGSERR"}
# FLASH_CR: PG 0, SER 1, MER 2, SNB 6:3, PSIZE 9:8 (x8, x16, x32, x64), STRT 16, LOCK 31.
CR_PG, CR_SER, CR_MER, CR_STRT, CR_LOCK = 1, 1 << 1, 1 << 2, 1 << 16, 1 << 31
PSIZE_BYTES = (1, 2, 4, 8)
# How long the CPU stalls on the flash, at most (the datasheet, DS8626, "Flash memory
# programming": word programming 100 µs, a 16 KiB sector's erase 500 ms at x32 parallelism).
PROGRAM_WORD_US = 100
ERASE_16K_US = 500_000
# FLASH_SR reads that show BSY after an operation starts.
BUSY_READS = 3
# ADC1 converts at each TIM2 update: every 100 µs while TIM2 counts.
SAMPLE_PERIOD_US = 100
NVIC_ISER, NVIC_ICER, NVIC_ISPR, NVIC_ICPR = 0xE000_E100, 0xE000_E180, 0xE000_E200, 0xE000_E280
NVIC_IPR, NVIC_STIR = 0xE000_E400, 0xE000_EF00
# SysTick and the system control block (PM0214 §4.4.3 ICSR, §4.4.4 AIRCR, §4.4.8 SHPR3, §4.5.1
# STK_CTRL).
SYST_CSR, SCB_ICSR, SCB_AIRCR, SCB_SHPR3 = 0xE000_E010, 0xE000_ED04, 0xE000_ED0C, 0xE000_ED20
EXC_SYSTICK = 15
PENDSTSET, COUNTFLAG, SYSRESETREQ, VECTKEY = 1 << 26, 1 << 16, 1 << 2, 0x05FA

IRQ_ADC, IRQ_USART2, IRQ_DMA2_STREAM2 = 18, 38, 58
ADC_SR_FLAGS = 0x3F
EOC, STRT, OVR = 1 << 1, 1 << 4, 1 << 5
TCIF2, TEIF2, DMEIF2 = 1 << 21, 1 << 19, 1 << 18
LOWEST_PRIORITY = 0xF0
THREAD_PRIORITY = 0x100
# xPSR's IT/ICI bits, 26:25 and 15:10 (ARMv7-M ARM §B1.4.2).
XPSR_IT = 0b11 << 25 | 0x3F << 10
BOOT_INSNS = 60_000_000
# The force sensor's code with nothing on it (the sampling phase's).
IDLE_CODE = 248
HANDLER_INSNS = 5_000_000

# Reset values that start-up reads back (RM0090 §7.3, §8.4, §10.5.10, §21.4).
RESET_VALUES = {
    RCC_CR: 0x0000_0083,
    RCC_PLLCFGR: 0x2400_3010,
    RCC_CSR: 0x0E00_0000,
    GPIOA + 0x00: 0xA800_0000,
    GPIOA + 0x08: 0x0C00_0000,
    GPIOA + 0x0C: 0x6400_0000,
    DMA2_S2FCR: 0x0000_0021,
    IWDG_RLR: 0x0000_0FFF,
    USART_SR: 0x0000_00C0,
}


class Failure(Exception):
    pass


class SystemReset(Exception):
    """The image asked for a system reset (AIRCR.SYSRESETREQ)."""


class Output:
    """The trace's lines, shared by the runs of one scenario (their numbers go on)."""

    def __init__(self):
        self.seq = 0
        self.lines = []


class Rig:
    """One power-up of the board: the image loaded, its flash as `store` (the bytes of sectors
    1–2 of an earlier run, or erased), `out` the trace to append to."""

    def __init__(self, elf_path, out=None, store=None, protected=()):
        with open(elf_path, "rb") as f:
            elf = ELFFile(f)
            self.segments = [(s["p_paddr"], s.data()) for s in elf.iter_segments()
                             if s["p_type"] == "PT_LOAD" and s["p_filesz"] > 0]
            text = elf.get_section_by_name(".text")
            self.text = (text["sh_addr"], text.data())
            self.symbols = {}
            symtab = elf.get_section_by_name(".symtab")
            if symtab is not None:
                for sym in symtab.iter_symbols():
                    if sym["st_info"]["type"] == "STT_FUNC" and sym["st_value"]:
                        self.symbols.setdefault(sym["st_value"] & ~1, sym.name)
        uc = Uc(UC_ARCH_ARM, UC_MODE_THUMB | UC_MODE_MCLASS)
        uc.ctl_set_cpu_model(UC_CPU_ARM_CORTEX_M4)
        # The flash: the store's sectors through `_store_read`/`_store_write` (programming is
        # the flash interface's, not a memory write); the others read-only (a store there
        # comes to `_on_protected`). (Not memory written from the hooks: unicorn crashes when
        # a read-only region is written while it runs.)
        store_end = STORE[0] + STORE[1]
        uc.mem_map(FLASH[0], STORE[0] - FLASH[0], UC_PROT_READ | UC_PROT_EXEC)
        uc.mmio_map(STORE[0], STORE[1], self._store_read, None, self._store_write, None)
        uc.mem_map(store_end, FLASH[0] + FLASH[1] - store_end, UC_PROT_READ | UC_PROT_EXEC)
        for base, size in (SYSMEM, CCM, SRAM, PERIPH, SCS):
            uc.mem_map(base, size)
        # Erased flash reads 0xFF (RM0090 §3.6.3); a board is flashed sector by sector, so the
        # store's sectors keep what they held.
        uc.mem_write(FLASH[0], b"\xff" * (STORE[0] - FLASH[0]))
        uc.mem_write(store_end, b"\xff" * (FLASH[0] + FLASH[1] - store_end))
        self.store = bytearray(store if store is not None else b"\xff" * STORE[1])
        if len(self.store) != STORE[1]:
            raise Failure(f"a store of {len(self.store)} bytes, not {STORE[1]}")
        for addr, data in self.segments:
            if addr < store_end and addr + len(data) > STORE[0]:
                raise Failure(f"the image puts bytes at 0x{addr:08x}..0x{addr + len(data):08x}, "
                              f"in the store's sectors")
            uc.mem_write(addr, data)
        uc.mem_write(RETURN_TRAP, b"\xfe\xe7" * 8)  # b .
        uc.mem_write(VREFINT_CAL, struct.pack("<H", 1500))
        for addr, value in RESET_VALUES.items():
            uc.mem_write(addr, struct.pack("<I", value))
        self.uc = uc
        self.out = out if out is not None else Output()
        self.adc_sr = {ADC1: 0, ADC2: 0}
        self.lisr = 0
        self.rx = []
        self.tx = bytearray()
        self.enabled = set()
        self.pending = set()
        self.stop_reason = None
        self.interrupts_on = False
        # The execution priorities of the handlers running (nested), innermost last.
        self.active = []
        # The flash interface: FLASH_CR from its reset value (LOCK), FLASH_SR, the key
        # sequence's progress, a wrong sequence (FLASH_CR locked until reset, §3.6.1), the
        # operation under way (FLASH_SR reads left with BSY, how long the CPU stalls).
        self.flash_cr = CR_LOCK
        self.flash_sr = 0
        self.keys_seen = 0
        self.flash_locked_out = False
        # Sectors the option bytes write-protect (FLASH_OPTCR.nWRP bits 0, §3.7.1, §3.9.7).
        self.protected = set(protected)
        self.busy_reads = 0
        self.stall_us = 0
        uc.hook_add(UC_HOOK_MEM_READ, self._on_read, begin=PERIPH[0], end=PERIPH[0] + PERIPH[1] - 1)
        uc.hook_add(UC_HOOK_MEM_WRITE, self._on_write, begin=PERIPH[0], end=PERIPH[0] + PERIPH[1] - 1)
        uc.hook_add(UC_HOOK_MEM_READ, self._on_read, begin=SCS[0], end=SCS[0] + SCS[1] - 1)
        uc.hook_add(UC_HOOK_MEM_WRITE, self._on_write, begin=SCS[0], end=SCS[0] + SCS[1] - 1)
        uc.hook_add(UC_HOOK_MEM_WRITE_PROT, self._on_protected)
        base, code = self.text
        for off in range(0, len(code) - 1, 2):
            hw = code[off] | code[off + 1] << 8
            if hw == 0xB662:  # cpsie i
                uc.hook_add(UC_HOOK_CODE, self._on_cpsie, begin=base + off, end=base + off)
            elif hw == 0xBF30:  # wfi
                uc.hook_add(UC_HOOK_CODE, self._on_wfi, begin=base + off, end=base + off)
        uc.hook_add(UC_HOOK_CODE, self._on_return, begin=RETURN_TRAP, end=RETURN_TRAP + 1)
        self.stop_wanted = None
        uc.hook_add(UC_HOOK_BLOCK, self._on_block)
        # SysTick: a wrap not yet read (STK_CTRL.COUNTFLAG), the exception pended (ICSR).
        self.systick_wrapped = False
        self.systick_pending = False

    # -- the trace -------------------------------------------------------------------------
    def event(self, kind, *fields):
        self.out.seq += 1
        self.out.lines.append(" ".join([kind, str(self.out.seq)] + [str(f) for f in fields]))

    def mark(self, kind, text=""):
        self.event("M", kind, text) if text else self.event("M", kind)

    def pc(self):
        return self.uc.reg_read(UC_ARM_REG_PC)

    # -- memory ----------------------------------------------------------------------------
    def read32(self, addr):
        return struct.unpack("<I", self.uc.mem_read(addr, 4))[0]

    def write32(self, addr, value):
        self.uc.mem_write(addr, struct.pack("<I", value & 0xFFFF_FFFF))

    def _load(self, addr, size):
        return int.from_bytes(self.uc.mem_read(addr, size), "little")

    def _store(self, addr, size, value):
        self.uc.mem_write(addr, (value & ((1 << (8 * size)) - 1)).to_bytes(size, "little"))

    def _modelled(self, addr):
        """The value a read of `addr` returns, or None for plain memory."""
        word = addr & ~3
        if word == RCC_CR:
            v = self.read32(RCC_CR)
            for on, rdy in ((0, 1), (16, 17), (24, 25), (26, 27)):
                if v >> on & 1:
                    v |= 1 << rdy
            return v
        if word == RCC_CFGR:
            v = self.read32(RCC_CFGR)
            return (v & ~0xC) | ((v & 3) << 2)
        if word == RCC_CSR:
            return self.read32(RCC_CSR) | 0x2
        for adc in (ADC1, ADC2):
            if word == adc + ADC_SR:
                return self.adc_sr[adc]
            if word == adc + ADC_CR2:
                # SWSTART and JSWSTART are cleared by the hardware once the conversion starts.
                return self.read32(word) & ~(1 << 30 | 1 << 22)
            if word == adc + ADC_DR:
                self.adc_sr[adc] &= ~EOC
                return None
        if word == DMA_LISR:
            return self.lisr
        if word == SYST_CSR:
            # COUNTFLAG reads 1 once after each wrap (PM0214 §4.5.1).
            v = self.read32(SYST_CSR) & ~COUNTFLAG | (COUNTFLAG if self.systick_wrapped else 0)
            self.systick_wrapped = False
            return v
        if word == FLASH_SR:
            return self._flash_sr_read()
        if word == FLASH_CR:
            return self.flash_cr
        if word == FLASH_KEYR:
            return 0
        if word == USART_SR:
            return 0xC0 | (0x20 if self.rx else 0)
        if word == USART_DR:
            return self.rx.pop(0) if self.rx else 0
        if NVIC_ISER <= word < NVIC_ISER + 0x20:
            return self._bits_of(self.enabled, word - NVIC_ISER)
        if NVIC_ISPR <= word < NVIC_ISPR + 0x20:
            return self._bits_of(self.pending, word - NVIC_ISPR)
        return None

    @staticmethod
    def _bits_of(irqs, offset):
        base = offset * 8
        return sum(1 << (n - base) for n in irqs if base <= n < base + 32)

    def _on_read(self, uc, access, addr, size, value, user):
        v = self._modelled(addr)
        if v is not None:
            shift = 8 * (addr & 3)
            self._store(addr, size, v >> shift)
        self.event("R", hex(addr), size, hex(self._load(addr, size)), hex(self.pc()))
        self._it_state_after_hook()

    def _on_write(self, uc, access, addr, size, value, user):
        self._it_state_after_hook()
        value &= (1 << (8 * size)) - 1
        self.event("W", hex(addr), size, hex(value), hex(self.pc()))
        if BITBAND[0] <= addr < BITBAND[0] + BITBAND[1]:
            # A bit-band alias (PM0214 §2.2.5): one bit of the peripheral word it maps.
            off = addr - BITBAND[0]
            byte = off // 32
            target, bit = PERIPH[0] + (byte & ~3), (byte & 3) * 8 + off % 32 // 4
            old = self._modelled(target)
            old = self.read32(target) if old is None else old
            new = (old | 1 << bit) if value & 1 else (old & ~(1 << bit))
            self.write32(target, new)
            self.event("B", hex(target), bit, value & 1, hex(self.pc()))
            if target in (FLASH_CR, FLASH_SR, FLASH_KEYR):
                self._flash_register_write(target, new if target != FLASH_SR else 1 << bit)
            return
        word = addr & ~3
        v32 = value << (8 * (addr & 3))
        for adc in (ADC1, ADC2):
            if word == adc + ADC_SR:
                self.adc_sr[adc] &= v32 | ~ADC_SR_FLAGS
            elif word == adc + ADC_CR2 and v32 & (1 << 30):
                self.adc_sr[adc] |= EOC | STRT
                self.write32(adc + ADC_DR, 1500)
        if word in (FLASH_CR, FLASH_SR, FLASH_KEYR):
            self._flash_register_write(word, v32)
        elif word == DMA_LIFCR:
            self.lisr &= ~v32
        elif word == USART_DR:
            self.tx.append(value & 0xFF)
        elif NVIC_ISER <= word < NVIC_ISER + 0x20:
            self.enabled |= self._irqs_of(v32, word - NVIC_ISER)
        elif NVIC_ICER <= word < NVIC_ICER + 0x20:
            self.enabled -= self._irqs_of(v32, word - NVIC_ICER)
        elif NVIC_ISPR <= word < NVIC_ISPR + 0x20:
            self.pending |= self._irqs_of(v32, word - NVIC_ISPR)
        elif NVIC_ICPR <= word < NVIC_ICPR + 0x20:
            self.pending -= self._irqs_of(v32, word - NVIC_ICPR)
        elif word == NVIC_STIR:
            self.pending.add(value & 0x1FF)
        elif word == SCB_ICSR and v32 & PENDSTSET:
            self.systick_pending = True
        elif word == SCB_AIRCR and v32 >> 16 == VECTKEY and v32 & SYSRESETREQ:
            self.mark("system-reset")
            self.stop_wanted = "system-reset"

    # -- the flash interface (RM0090 §3.5–3.9) ------------------------------------------------
    def _flash_error(self, flag, detail):
        """An operation the flash refuses: its FLASH_SR flag set, the trace told."""
        self.flash_sr |= flag
        self.mark("flash-error", f"{SR_NAMES[flag]} {detail}")

    def _flash_register_write(self, word, v32):
        if word == FLASH_KEYR:
            # §3.6.1: KEY1 then KEY2 clear LOCK; anything else (a wrong key, a key while
            # unlocked) is a bus error and FLASH_CR stays locked until the next reset.
            expected = FLASH_KEYS[self.keys_seen] if self.flash_cr & CR_LOCK else None
            if self.flash_locked_out or v32 != expected:
                self.flash_locked_out = True
                self.keys_seen = 0
                self.mark("flash-error", f"KEYR 0x{v32:08x}")
            elif self.keys_seen == 1:
                self.keys_seen = 0
                self.flash_cr &= ~CR_LOCK
            else:
                self.keys_seen = 1
        elif word == FLASH_SR:
            # rc_w1 flags (§3.9.4); BSY is read-only.
            self.flash_sr &= ~(v32 & SR_RC_W1)
        elif word == FLASH_CR:
            if self.flash_cr & CR_LOCK:
                # §3.9.5: FLASH_CR is written only once unlocked.
                self.mark("flash-error", f"CR-LOCKED 0x{v32:08x}")
                return
            # LOCK is set by software only (cleared by the key sequence); STRT stays set until
            # BSY clears.
            self.flash_cr = v32 | (self.flash_cr & CR_STRT)
            if v32 & CR_STRT and not self.busy_reads:
                self._flash_start_erase(v32)

    def _flash_start_erase(self, cr):
        """STRT: a sector erase (SER, SNB) or a mass erase (MER), §3.6.3."""
        if cr & CR_MER:
            self._flash_error(SR_WRPERR, "mass-erase")
            return
        if not cr & CR_SER:
            self.mark("flash-error", f"STRT-WITHOUT-SER 0x{cr:08x}")
            return
        snb = cr >> 3 & 0xF
        if snb not in STORE_SECTORS or snb in self.protected:
            self._flash_error(SR_WRPERR, f"erase sector {snb}")
            return
        off = SECTOR_BASES[snb] - STORE[0]
        self.store[off:off + SECTOR_SIZES[snb]] = b"\xff" * SECTOR_SIZES[snb]
        self.mark("flash-erase", str(snb))
        self._flash_busy(ERASE_16K_US)

    def _flash_program(self, addr, size, value):
        """A CPU store into the flash (§3.6.4): programmed with PG and the access size that
        PSIZE says; bits only cleared (a word programmed again ANDs into it)."""
        cr = self.flash_cr
        if cr & CR_LOCK or not cr & CR_PG or cr & (CR_SER | CR_MER) or self.busy_reads:
            self._flash_error(SR_PGSERR, hex(addr))
        elif size != PSIZE_BYTES[cr >> 8 & 3]:
            self._flash_error(SR_PGPERR, f"{hex(addr)} size {size}")
        elif addr % 16 + size > 16:
            # The data must fit in one 128-bit row.
            self._flash_error(SR_PGAERR, hex(addr))
        elif not STORE[0] <= addr < STORE[0] + STORE[1] or self._sector(addr) in self.protected:
            self._flash_error(SR_WRPERR, hex(addr))
        else:
            off = addr - STORE[0]
            old = int.from_bytes(self.store[off:off + size], "little")
            self.store[off:off + size] = (old & value).to_bytes(size, "little")
            self._flash_busy(PROGRAM_WORD_US)

    @staticmethod
    def _sector(addr):
        return max(n for n, base in enumerate(SECTOR_BASES) if base <= addr)

    def _flash_busy(self, stall_us):
        self.busy_reads = BUSY_READS
        self.stall_us = stall_us

    def _flash_sr_read(self):
        v = self.flash_sr | (SR_BSY if self.busy_reads else 0)
        if self.busy_reads:
            self.busy_reads -= 1
            if not self.busy_reads:
                self._flash_done()
        return v

    def _flash_done(self):
        """The operation ends: the CPU, stalled on the flash meanwhile (§3.6.3–3.6.4), goes on
        `stall_us` later; ADC1 converted on every TIM2 update in between, and the sampling
        interrupt, if it preempts what runs, is taken at once (`run` delivers it)."""
        self.flash_cr &= ~CR_STRT
        self.set_time_us(self.read32(TIM5_CNT) + self.stall_us)
        conversions = self.stall_us // SAMPLE_PERIOD_US if self.read32(TIM2_CR1) & 1 else 0
        if conversions:
            overrun = conversions > 1 or self.adc_sr[ADC1] & EOC
            self.write32(ADC1 + ADC_DR, IDLE_CODE)
            self.adc_sr[ADC1] |= EOC | STRT | (OVR if overrun else 0)
            if self.interrupts_on:
                # The interrupt is taken at the next block: a stop asked for from a memory hook
                # inside an IT block is lost (unicorn 2.1.4), and the BSY loops' reads are there.
                self.stop_wanted = "flash-done"

    def _on_block(self, uc, addr, size, user):
        if self.stop_wanted:
            self.stop_reason, self.stop_wanted = self.stop_wanted, None
            uc.emu_stop()

    def _it_state_after_hook(self):
        """A memory hook on an instruction inside an IT block leaves that instruction's IT
        state in the CPU (unicorn restores the state of the instruction for the hook); no
        later instruction outside the block clears it, and the next block looked up (after a
        stop, or the first time a branch is taken) would run its instructions conditionally.
        The blocks end after their IT blocks (a branch): cleared."""
        xpsr = self.uc.reg_read(UC_ARM_REG_XPSR)
        if xpsr & XPSR_IT:
            self.uc.reg_write(UC_ARM_REG_XPSR, xpsr & ~XPSR_IT)

    def _store_read(self, uc, offset, size, user):
        return int.from_bytes(self.store[offset:offset + size], "little")

    def _store_write(self, uc, offset, size, value, user):
        self._it_state_after_hook()
        addr = STORE[0] + offset
        value &= (1 << (8 * size)) - 1
        self.event("W", hex(addr), size, hex(value), hex(self.pc()))
        self._flash_program(addr, size, value)

    def _on_protected(self, uc, access, addr, size, value, user):
        """A store into the flash outside the store's sectors: refused (not written)."""
        self._it_state_after_hook()
        if not FLASH[0] <= addr < FLASH[0] + FLASH[1]:
            return False
        value &= (1 << (8 * size)) - 1
        self.event("W", hex(addr), size, hex(value), hex(self.pc()))
        self._flash_program(addr, size, value)
        return True

    @staticmethod
    def _irqs_of(bits, offset):
        return {offset * 8 + i for i in range(32) if bits >> i & 1}

    # -- execution -------------------------------------------------------------------------
    def _on_cpsie(self, uc, addr, size, user):
        if not self.interrupts_on:
            self.interrupts_on = True
            self.stop_reason = "cpsie"
            uc.emu_stop()

    def _on_wfi(self, uc, addr, size, user):
        if self.stop_reason is None:
            self.stop_reason = "wfi"
            uc.emu_stop()

    def _on_return(self, uc, addr, size, user):
        self.stop_reason = "return"
        uc.emu_stop()

    def run(self, start, count, what):
        pc = start
        for _ in range(100_000):
            self.stop_reason = None
            try:
                self.uc.emu_start(pc | 1, 0xFFFF_FFFF, count=count)
            except UcError as e:
                raise Failure(f"{what}: {e} at pc=0x{self.pc():08x}") from e
            if self.stop_reason != "flash-done":
                return self.stop_reason
            # The flash let the CPU go on: what preempts the code that stalled runs first.
            pc = self.pc()
            self.preempt()
        raise Failure(f"{what}: 100,000 flash operations")

    def execution_priority(self):
        """The priority an interrupt must beat to preempt (PM0214 §2.3.7): the running
        handler's, BASEPRI's, PRIMASK's."""
        if self.uc.reg_read(UC_ARM_REG_PRIMASK) & 1:
            return 0
        prio = self.active[-1] if self.active else THREAD_PRIORITY
        basepri = self.uc.reg_read(UC_ARM_REG_BASEPRI) & 0xFF
        return min(prio, basepri) if basepri else prio

    def preempt(self):
        """Delivers the interrupts ready whose priority beats the execution priority."""
        for _ in range(1_000):
            limit = self.execution_priority()
            ready = [n for n in self.ready() if self.priority(n) < limit]
            if not ready:
                return
            self.deliver(min(ready, key=lambda n: (self.priority(n), n)))
        raise Failure("interrupts still preempting after 1,000 deliveries")

    def boot(self, phase="boot"):
        self.mark("power-up")
        self.mark("phase", phase)
        sp, reset = struct.unpack("<II", self.uc.mem_read(FLASH[0], 8))
        self.uc.reg_write(UC_ARM_REG_SP, sp)
        if self.run(reset, BOOT_INSNS, "start-up") != "cpsie":
            raise Failure(f"start-up: interrupts never came on (stopped at pc=0x{self.pc():08x})")
        # Execute the cpsie itself, then the CPU takes what is pending.
        cpsie = self.pc()
        self.run(cpsie, 1, "cpsie")
        self.mark("interrupts-on")
        self.deliver_pending()
        if self.run(self.pc(), BOOT_INSNS, "after init") != "wfi":
            raise Failure(f"after init: no idle loop reached (pc=0x{self.pc():08x})")
        self.mark("idle")

    def priority(self, irq):
        return self.uc.mem_read(NVIC_IPR + irq, 1)[0]

    def level_pending(self):
        """Interrupts raised by a peripheral's flag and enable."""
        out = set()
        cr1 = self.read32(ADC1 + ADC_CR1)
        if cr1 & (1 << 5) and self.adc_sr[ADC1] & EOC:
            out.add(IRQ_ADC)
        if cr1 & (1 << 26) and self.adc_sr[ADC1] & OVR:
            out.add(IRQ_ADC)
        ucr1 = self.read32(USART_CR1)
        if ucr1 & (1 << 7) or (ucr1 & (1 << 5) and self.rx):
            out.add(IRQ_USART2)
        s2cr = self.read32(S2CR)
        if (s2cr & (1 << 4) and self.lisr & TCIF2) or (s2cr & (1 << 2) and self.lisr & TEIF2) \
                or (s2cr & (1 << 1) and self.lisr & DMEIF2):
            out.add(IRQ_DMA2_STREAM2)
        return out

    def ready(self):
        return [n for n in (self.pending | self.level_pending()) & self.enabled
                if self.priority(n) != LOWEST_PRIORITY]

    def deliver_pending(self, limit=2_000):
        for _ in range(limit):
            ready = self.ready()
            if not ready:
                return
            self.deliver(min(ready, key=lambda n: (self.priority(n), n)))
        raise Failure(f"interrupts still pending after {limit} deliveries: {sorted(self.ready())}")

    def deliver(self, irq):
        self.pending.discard(irq)
        self._handle(16 + irq, self.priority(irq), "irq", irq)

    def _handle(self, exception, priority, kind, n):
        """Runs the handler of `exception` (its vector's number) to its end."""
        handler = self.read32(FLASH[0] + 4 * exception) & ~1
        name = self.symbols.get(handler, hex(handler))
        self.mark(kind, f"{n} {name}")
        ctx = self.uc.context_save()
        sp = self.uc.reg_read(UC_ARM_REG_SP)
        self.uc.reg_write(UC_ARM_REG_SP, (sp - 0x68) & ~7)  # room for an extended frame
        self.uc.reg_write(UC_ARM_REG_LR, RETURN_TRAP | 1)
        self.active.append(priority)
        stop = self.run(handler, HANDLER_INSNS, f"{kind} {n} ({name})")
        if stop == "system-reset":
            raise SystemReset()
        if stop != "return":
            raise Failure(f"{kind} {n} ({name}) did not return within {HANDLER_INSNS} "
                          f"instructions (pc=0x{self.pc():08x})")
        self.active.pop()
        self.uc.context_restore(ctx)

    def systick(self, ms):
        """`ms` SysTick periods (1 kHz, the RTIC monotonic): TIM5 moves on 1 ms each, the
        counter wraps and its exception is taken when enabled (STK_CTRL ENABLE and TICKINT),
        then what it made pending. A system reset ends it (`SystemReset`)."""
        for _ in range(ms):
            self.set_time_us(self.read32(TIM5_CNT) + 1000)
            self.systick_wrapped = True
            if self.read32(SYST_CSR) & 3 == 3:
                self.systick_pending = True
            while self.systick_pending:
                self.systick_pending = False
                self._handle(EXC_SYSTICK, self.uc.mem_read(SCB_SHPR3 + 3, 1)[0], "exception",
                             EXC_SYSTICK)
                self.deliver_pending()

    # -- the scenario's stimuli ------------------------------------------------------------
    def set_time_us(self, us):
        self.write32(TIM5_CNT, us)

    def adc1_conversion(self, code, overrun=False):
        self.write32(ADC1 + ADC_DR, code)
        self.adc_sr[ADC1] |= EOC | STRT | (OVR if overrun else 0)
        self.deliver_pending()

    def console(self, line):
        self.tx.clear()
        self.rx.extend(line.encode() + b"\r")
        self.deliver_pending()
        text = self.tx.decode(errors="replace")
        reply = text.split("\r\n")[0] if "\r\n" in text else text
        self.mark("reply", reply)
        return reply

    def dma_block(self, codes):
        """The stream fills the buffer it is on (CT) and switches to the other (§10.3.9)."""
        cr = self.read32(S2CR)
        if not cr & 1:
            # A disabled stream transfers nothing and flags nothing.
            self.mark("stream-disabled")
            return
        target = S2M1AR if cr & (1 << 19) else S2M0AR
        buf = self.read32(target)
        self.uc.mem_write(buf, struct.pack(f"<{len(codes)}H", *codes))
        self.write32(S2CR, cr ^ (1 << 19))
        self.write32(S2NDTR, len(codes))
        self.lisr |= TCIF2
        self.deliver_pending()

    def dma_transfer_error(self):
        """A bus error: TEIF2 set and the stream disabled by the hardware (§10.3.18); ADC2
        then overruns (§13.8.1)."""
        self.write32(S2CR, self.read32(S2CR) & ~1)
        self.lisr |= TEIF2
        self.adc_sr[ADC2] |= OVR | EOC
        self.deliver_pending()


def scenario(elf, out):
    """The runs, in order, into `out`."""
    rig = Rig(elf, out)
    rig.boot()

    rig.mark("phase", "sample")
    rig.set_time_us(10_000)
    rig.adc1_conversion(IDLE_CODE)
    rig.set_time_us(10_100)
    rig.adc1_conversion(250)

    # Another rig and gap, kept: the store's sectors programmed while the sampling goes on
    # (an ADC1 conversion at every 100 µs of flash stall); the sampling task's deadline checks
    # hold.
    rig.mark("phase", "save")
    rig.set_time_us(10_150)
    rig.console("rig beam-150")
    rig.console("gap 1.5")
    rig.console("save")
    rig.console("status")

    rig.mark("phase", "revert")
    rig.console("revert")

    rig.mark("phase", "capture-arm")
    rig.set_time_us(20_000)
    rig.console("capture arm 1 0.5")

    rig.mark("phase", "console-armed")
    rig.console("status")

    rig.mark("phase", "capture-block")
    rig.set_time_us(20_650)
    rig.dma_block([248] * 64)
    rig.console("capture")

    rig.mark("phase", "capture-error")
    rig.set_time_us(21_650)
    rig.dma_transfer_error()
    rig.console("capture")

    rig.mark("phase", "capture-rearm")
    rig.console("capture stop")
    rig.set_time_us(30_000)
    rig.console("capture arm 1 0.5")

    rig.mark("phase", "capture-stopped")
    rig.console("capture stop")
    rig.set_time_us(30_650)
    rig.dma_block([248] * 64)
    rig.set_time_us(31_300)
    rig.dma_block([248] * 64)

    rig.mark("phase", "adc-overrun")
    rig.set_time_us(40_000)
    rig.adc1_conversion(260, overrun=True)
    rig.mark("done")

    # The next power-up with the same flash: `init` loads what `save` wrote.
    saved = bytes(rig.store)
    rig = Rig(elf, rig.out, saved)
    rig.boot("reboot")
    rig.console("id")
    rig.console("store")
    # `reset`: the reply sent, then SYSRESETREQ after the monotonic's delays.
    rig.mark("phase", "reset")
    rig.console("reset")
    try:
        rig.systick(200)
    except SystemReset:
        pass
    else:
        raise Failure("`reset`: no system reset within 200 ms")
    rig = Rig(elf, rig.out, bytes(rig.store))
    rig.boot("after-reset")
    rig.console("id")
    rig.mark("done")

    # A power-up after a cut as the store moved to its other sector: sector 2 full and closed
    # (the first run's items, its last word programmed: sequential-storage's end marker),
    # sector 1 just opened (its first word programmed: the start marker), nothing moved yet.
    # It loads; the next `save` finishes the move (sector 1 erased, the items copied, sector 2
    # erased) while the sampling goes on through 500 ms stalls.
    half = STORE[1] // 2
    moved = bytearray(b"\xff" * STORE[1])
    moved[:4] = bytes(4)
    moved[half:] = saved[:half]
    moved[-4:] = bytes(4)
    rig = Rig(elf, rig.out, bytes(moved))
    rig.boot("cut-boot")
    rig.console("id")
    rig.mark("phase", "cut-save")
    rig.set_time_us(10_000)
    rig.adc1_conversion(IDLE_CODE)
    rig.set_time_us(10_100)
    rig.adc1_conversion(IDLE_CODE)
    rig.console("save")
    rig.console("status")
    # The same overrun, the deadline checks not paused: a fault.
    rig.mark("phase", "cut-overrun")
    rig.set_time_us(rig.read32(TIM5_CNT) + 100)
    rig.adc1_conversion(IDLE_CODE, overrun=True)
    rig.console("status")
    rig.mark("done")

    # A board whose option bytes write-protect the store's sectors: the save's first word is
    # refused (WRPERR); the driver clears the flag, locks the flash and the save fails.
    rig = Rig(elf, rig.out, bytes(rig.store), protected=STORE_SECTORS)
    rig.boot("wrp-boot")
    rig.mark("phase", "wrp-save")
    rig.set_time_us(10_000)
    rig.adc1_conversion(IDLE_CODE)
    rig.console("gap 2")
    rig.console("save")
    rig.console("status")
    rig.mark("done")


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("elf")
    ap.add_argument("--out", help="write the trace here instead of stdout")
    args = ap.parse_args()
    out = Output()
    status = 0
    try:
        scenario(args.elf, out)
    except Failure as e:
        out.seq += 1
        out.lines.append(f"M {out.seq} error {e}")
        status = 1
    text = "\n".join(out.lines) + "\n"
    if args.out:
        with open(args.out, "w") as f:
            f.write(text)
    else:
        sys.stdout.write(text)
    if status:
        print(f"register_trace.py: {out.lines[-1]}", file=sys.stderr)
    return status


if __name__ == "__main__":
    sys.exit(main())
