//! Which vector instructions the host's lane kernels ([`super::lanes`], `contact_lanes`,
//! `switch_lanes`, `near`) run, chosen at run time from what the CPU reports, and the one place
//! that compiles a kernel for each ([`Kernel`], [`Isa::run`]).
//!
//! The variants compile the same source with more instructions enabled: the same operations
//! in the same order and no fused multiply-add (Rust never contracts `a * b + c`), so every
//! variant gives the same bits. On the MCU (no `std`) the kernels are the portable code.
//! Besides, [`Isa::gather`]: a table read in every lane at once where the variant has an
//! instruction for it.

#[cfg(all(feature = "std", target_arch = "x86_64"))]
use crate::real::Real;

/// A lane kernel's body with its arguments, run by [`Isa::run`] in the instruction set asked
/// for. Implementations mark [`Kernel::run`] `#[inline(always)]` (and whatever it calls that
/// should vectorise), so that the body compiles into each variant.
pub(crate) trait Kernel {
    /// What the kernel returns.
    type Output;
    /// The body, compiled for the variant `I` (which it may ask for what only that variant
    /// has, [`Variant::ISA`]: known at compile time).
    fn run<I: Variant>(self) -> Self::Output;
}

/// The variant a [`Kernel`] is being compiled for, as a type ([`Isa::run`] picks it after
/// [`Isa::detect`]; nothing else names the types).
pub(crate) trait Variant {
    /// Its instruction set.
    const ISA: Isa;
    /// Whether the free-flight lanes take the peak test (a division) only in the rounds where
    /// a lane turned round: with AVX-512's mask registers the test costs a branch and saves
    /// the division's latency; the other variants take it in every round.
    const SPLIT_PEAK_TEST: bool = false;
}

/// [`Isa::Portable`] as a [`Variant`].
pub(crate) struct PortableCode;

impl Variant for PortableCode {
    const ISA: Isa = Isa::Portable;
}

/// [`Isa::Avx2`] as a [`Variant`].
#[cfg(all(feature = "std", target_arch = "x86_64"))]
pub(crate) struct Avx2Code;

#[cfg(all(feature = "std", target_arch = "x86_64"))]
impl Variant for Avx2Code {
    const ISA: Isa = Isa::Avx2;
}

/// [`Isa::Avx512`] as a [`Variant`].
#[cfg(all(feature = "std", target_arch = "x86_64"))]
pub(crate) struct Avx512Code;

#[cfg(all(feature = "std", target_arch = "x86_64"))]
impl Variant for Avx512Code {
    const ISA: Isa = Isa::Avx512;
    const SPLIT_PEAK_TEST: bool = true;
}

/// The instruction set a lane kernel runs, narrowest first.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
pub(crate) enum Isa {
    /// The target's baseline (SSE2 on x86-64; the Cortex-M4F's FPU on the MCU).
    Portable,
    /// AVX2: 8 `f32` per register.
    #[cfg(all(feature = "std", target_arch = "x86_64"))]
    Avx2,
    /// AVX-512 (F, VL, DQ, BW): 16 `f32` per register, 32 registers.
    #[cfg(all(feature = "std", target_arch = "x86_64"))]
    Avx512,
}

impl Isa {
    /// The widest variant this CPU runs (the standard library caches the CPU's answer); in
    /// tests, a narrower one while [`with_isa`] forces it.
    #[inline]
    pub(crate) fn detect() -> Isa {
        let widest = Self::widest();
        #[cfg(test)]
        if let Some(forced) = FORCED.with(|f| f.get())
            && forced <= widest
        {
            return forced;
        }
        widest
    }

    /// The variants this CPU runs, narrowest first.
    #[cfg(test)]
    pub(crate) fn supported() -> std::vec::Vec<Isa> {
        up_to(Self::widest())
    }

    /// Runs `kernel` compiled for this variant. The variant must be one the CPU runs: an
    /// [`Isa`] only comes from [`Isa::detect`] (or, in tests, `Isa::supported`).
    #[inline(always)]
    pub(crate) fn run<K: Kernel>(self, kernel: K) -> K::Output {
        match self {
            // SAFETY: the CPU supports the variant's instructions (`Isa::detect`).
            #[cfg(all(feature = "std", target_arch = "x86_64"))]
            #[allow(unsafe_code)]
            Isa::Avx512 => unsafe { run_avx512(kernel) },
            // SAFETY: as above.
            #[cfg(all(feature = "std", target_arch = "x86_64"))]
            #[allow(unsafe_code)]
            Isa::Avx2 => unsafe { run_avx2(kernel) },
            Isa::Portable => kernel.run::<PortableCode>(),
        }
    }

    /// `table[idx[i]]` in every lane `i`, as one gather instruction where this variant has
    /// one for `L` lanes of `T` (AVX-512: 16 `f32`) and every index is in range; `None`
    /// elsewhere, and the caller reads the lanes one by one. The same values either way. As
    /// with [`Isa::run`], the variant must be one the CPU runs ([`Isa::detect`], or the
    /// [`Variant`] a kernel is compiled for).
    #[cfg(all(feature = "std", target_arch = "x86_64"))]
    #[inline(always)]
    pub(crate) fn gather<T: Real, const L: usize, const N: usize>(
        self,
        table: &[T; N],
        idx: &[u32; L],
    ) -> Option<[T; L]> {
        if self == Isa::Avx512 {
            use core::any::Any;
            // Only `f32` in 16 lanes (the types are known at compile time: the casts fold).
            let mut out = [T::zero(); L];
            if let (Some(t), Some(i), Some(o)) = (
                (table as &dyn Any).downcast_ref::<[f32; N]>(),
                (idx as &dyn Any).downcast_ref::<[u32; 16]>(),
                (&mut out as &mut dyn Any).downcast_mut::<[f32; 16]>(),
            ) {
                // SAFETY: the CPU supports AVX-512 (`Isa::detect`).
                #[allow(unsafe_code)]
                let got = unsafe { gather_avx512(t, i) }?;
                *o = got;
                return Some(out);
            }
        }
        None
    }

    /// The name [`ISA_VAR`] and [`kernel_isa`] use: `avx512`, `avx2` or `portable`.
    pub(crate) fn name(self) -> &'static str {
        match self {
            Isa::Portable => "portable",
            #[cfg(all(feature = "std", target_arch = "x86_64"))]
            Isa::Avx2 => "avx2",
            #[cfg(all(feature = "std", target_arch = "x86_64"))]
            Isa::Avx512 => "avx512",
        }
    }

    /// The widest variant the kernels may run: the widest the CPU reports, narrowed by
    /// [`ISA_VAR`] where that names a narrower one (read once).
    fn widest() -> Isa {
        #[cfg(feature = "std")]
        {
            static WIDEST: std::sync::OnceLock<Isa> = std::sync::OnceLock::new();
            *WIDEST.get_or_init(|| {
                let cpu = Self::cpu_widest();
                narrowed(cpu, std::env::var_os(ISA_VAR).as_deref()).unwrap_or(cpu)
            })
        }
        #[cfg(not(feature = "std"))]
        Self::cpu_widest()
    }

    /// The widest variant the CPU reports.
    fn cpu_widest() -> Isa {
        #[cfg(all(feature = "std", target_arch = "x86_64"))]
        {
            if std::is_x86_feature_detected!("avx512f")
                && std::is_x86_feature_detected!("avx512vl")
                && std::is_x86_feature_detected!("avx512dq")
                && std::is_x86_feature_detected!("avx512bw")
            {
                return Isa::Avx512;
            }
            if std::is_x86_feature_detected!("avx") && std::is_x86_feature_detected!("avx2") {
                return Isa::Avx2;
            }
        }
        Isa::Portable
    }
}

/// The environment variable that narrows the vector instructions of the host's lane kernels
/// below the widest the CPU runs: `avx2` or `portable` (`avx512`, or the variable unset or
/// empty: the widest). Every variant gives the same bits (module docs); this is for measuring
/// one variant on a CPU that also runs a wider one (docs/performance.md). Read once, when the
/// first kernel is made; [`check_isa_var`] says whether it names a variant this CPU runs (a
/// value that does not is ignored).
#[cfg(feature = "std")]
pub const ISA_VAR: &str = "VIBRO_ISA";

/// [`ISA_VAR`] names no variant this CPU runs.
#[cfg(feature = "std")]
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct IsaVarError {
    /// The variable's value (lossy where it is not UTF-8).
    pub value: std::string::String,
    /// The variants this CPU runs, narrowest first, by name.
    pub allowed: std::vec::Vec<&'static str>,
}

#[cfg(feature = "std")]
impl core::fmt::Display for IsaVarError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        write!(
            f,
            "{ISA_VAR}={:?}: expected one of the variants this CPU runs: {}",
            self.value,
            self.allowed.join(", ")
        )
    }
}

#[cfg(feature = "std")]
impl std::error::Error for IsaVarError {}

/// The variants up to `widest`, narrowest first.
#[cfg(any(test, feature = "std"))]
fn up_to(widest: Isa) -> std::vec::Vec<Isa> {
    [
        Isa::Portable,
        #[cfg(all(feature = "std", target_arch = "x86_64"))]
        Isa::Avx2,
        #[cfg(all(feature = "std", target_arch = "x86_64"))]
        Isa::Avx512,
    ]
    .into_iter()
    .filter(|&isa| isa <= widest)
    .collect()
}

/// The variant [`ISA_VAR`]'s value `var` asks for on a CPU whose widest is `cpu`: `cpu` if
/// unset or empty, the named one if the CPU runs it; an [`IsaVarError`] otherwise.
#[cfg(feature = "std")]
fn narrowed(cpu: Isa, var: Option<&std::ffi::OsStr>) -> Result<Isa, IsaVarError> {
    let Some(var) = var.filter(|v| !v.is_empty()) else {
        return Ok(cpu);
    };
    let allowed = up_to(cpu);
    allowed
        .iter()
        .copied()
        .find(|isa| var.to_str() == Some(isa.name()))
        .ok_or_else(|| IsaVarError {
            value: var.to_string_lossy().into_owned(),
            allowed: allowed.iter().map(|isa| isa.name()).collect(),
        })
}

/// The vector instructions the host's lane kernels run: `"avx512"`, `"avx2"` or `"portable"`
/// (the widest the CPU runs, or the narrower one the environment variable `VIBRO_ISA` names,
/// `ISA_VAR` with the `std` feature; always `"portable"` on the MCU).
pub fn kernel_isa() -> &'static str {
    Isa::detect().name()
}

/// Whether [`ISA_VAR`] is unset, empty or names a variant this CPU runs: the variant the
/// kernels run ([`kernel_isa`]); else an [`IsaVarError`] with the names allowed.
///
/// # Errors
/// [`IsaVarError`] where the value names no variant this CPU runs (`avx512` on an AVX2 CPU,
/// `sse2`, …).
#[cfg(feature = "std")]
pub fn check_isa_var() -> Result<&'static str, IsaVarError> {
    narrowed(Isa::cpu_widest(), std::env::var_os(ISA_VAR).as_deref()).map(Isa::name)
}

/// [`Kernel::run`] compiled for AVX-512.
#[cfg(all(feature = "std", target_arch = "x86_64"))]
#[target_feature(enable = "avx,avx2,avx512f,avx512vl,avx512dq,avx512bw")]
fn run_avx512<K: Kernel>(kernel: K) -> K::Output {
    kernel.run::<Avx512Code>()
}

/// [`Isa::gather`] for 16 `f32` lanes: `None` if an index is out of `table`'s range.
#[cfg(all(feature = "std", target_arch = "x86_64"))]
#[target_feature(enable = "avx512f")]
fn gather_avx512<const N: usize>(table: &[f32; N], idx: &[u32; 16]) -> Option<[f32; 16]> {
    use core::arch::x86_64::{
        _mm512_cmplt_epu32_mask, _mm512_i32gather_ps, _mm512_loadu_si512, _mm512_set1_epi32,
        _mm512_storeu_ps,
    };
    // Lengths beyond `i32` would not index as the instruction's signed offsets.
    let len = i32::try_from(N).ok()?;
    // SAFETY: `idx` is 16 `u32`, 64 bytes, read unaligned.
    #[allow(unsafe_code)]
    let j = unsafe { _mm512_loadu_si512(idx.as_ptr().cast()) };
    if _mm512_cmplt_epu32_mask(j, _mm512_set1_epi32(len)) != u16::MAX {
        return None;
    }
    let mut out = [0.0f32; 16];
    // SAFETY: every index is below `N` (the mask above), so every lane reads an element of
    // `table`; `out` is 16 `f32`, written unaligned.
    #[allow(unsafe_code)]
    unsafe {
        let v = _mm512_i32gather_ps::<4>(j, table.as_ptr().cast());
        _mm512_storeu_ps(out.as_mut_ptr(), v);
    }
    Some(out)
}

/// [`Kernel::run`] compiled for AVX2.
#[cfg(all(feature = "std", target_arch = "x86_64"))]
#[target_feature(enable = "avx,avx2")]
fn run_avx2<K: Kernel>(kernel: K) -> K::Output {
    kernel.run::<Avx2Code>()
}

#[cfg(test)]
std::thread_local! {
    static FORCED: core::cell::Cell<Option<Isa>> = const { core::cell::Cell::new(None) };
}

/// Runs `f` with the lane kernels created on this thread in `isa` (if the CPU runs it; else
/// the widest it runs), so that tests reach every variant.
#[cfg(test)]
pub(crate) fn with_isa<R>(isa: Isa, f: impl FnOnce() -> R) -> R {
    FORCED.with(|c| c.set(Some(isa)));
    let r = f();
    FORCED.with(|c| c.set(None));
    r
}

/// Whether this CPU has 16-`f32` vector registers (AVX-512), so that the grid analyses run
/// [`crate::analysis::WIDE_LANES`] protocol runs per core instead of
/// [`crate::analysis::DEFAULT_LANES`] ([`crate::analysis::lanes_per_core`]).
#[inline]
pub(crate) fn wide_vectors() -> bool {
    #[cfg(all(feature = "std", target_arch = "x86_64"))]
    if Isa::detect() == Isa::Avx512 {
        return true;
    }
    false
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tests_reach_every_variant_the_cpu_runs() {
        let all = Isa::supported();
        assert_eq!(all.first(), Some(&Isa::Portable));
        assert_eq!(all.last(), Some(&Isa::detect()));
        for &isa in &all {
            assert_eq!(with_isa(isa, Isa::detect), isa);
        }
        // Outside `with_isa` the widest again.
        assert_eq!(Isa::detect(), Isa::widest());
        assert_eq!(wide_vectors(), all.len() == 3);
    }

    #[cfg(feature = "std")]
    #[test]
    fn the_variable_narrows_to_a_variant_the_cpu_runs_and_nothing_else() {
        use std::ffi::OsStr;
        let all = Isa::supported();
        let cpu = Isa::cpu_widest();
        assert_eq!(narrowed(cpu, None), Ok(cpu));
        assert_eq!(narrowed(cpu, Some(OsStr::new(""))), Ok(cpu));
        for &isa in &all {
            assert_eq!(narrowed(cpu, Some(OsStr::new(isa.name()))), Ok(isa));
        }
        let names: std::vec::Vec<_> = all.iter().map(|isa| isa.name()).collect();
        for bad in ["sse2", "AVX2", " avx2", "avx"] {
            let e = narrowed(cpu, Some(OsStr::new(bad))).unwrap_err();
            assert_eq!(e.value, bad);
            assert_eq!(e.allowed, names);
            let text = e.to_string();
            assert!(
                text.starts_with("VIBRO_ISA=") && text.ends_with(&names.join(", ")),
                "{text}"
            );
        }
        // A CPU without AVX-512 refuses it; the portable one refuses both vector variants.
        #[cfg(all(feature = "std", target_arch = "x86_64"))]
        {
            let e = narrowed(Isa::Avx2, Some(OsStr::new("avx512"))).unwrap_err();
            assert_eq!(e.allowed, ["portable", "avx2"]);
            let e = narrowed(Isa::Portable, Some(OsStr::new("avx2"))).unwrap_err();
            assert_eq!(e.allowed, ["portable"]);
        }
        // Not UTF-8: refused, shown lossily.
        #[cfg(unix)]
        {
            use std::os::unix::ffi::OsStrExt;
            let e = narrowed(cpu, Some(OsStr::from_bytes(b"avx\xff"))).unwrap_err();
            assert_eq!(e.value, "avx\u{fffd}");
        }
    }

    #[cfg(all(feature = "std", target_arch = "x86_64"))]
    #[test]
    fn a_gather_reads_what_the_lanes_read_one_by_one() {
        let table: [f32; 40] = core::array::from_fn(|i| (i as f32).mul_add(0.37, -3.1));
        let idx: [u32; 16] = core::array::from_fn(|i| (7 * i as u32 + 3) % 40);
        let one_by_one = idx.map(|i| table[i as usize]);
        for isa in Isa::supported() {
            let got = isa.gather(&table, &idx);
            // Only AVX-512 gathers, and only 16 `f32` lanes.
            assert_eq!(got.is_some(), isa == Isa::Avx512, "{isa:?}");
            if let Some(got) = got {
                assert_eq!(got.map(f32::to_bits), one_by_one.map(f32::to_bits));
            }
            let eight: [u32; 8] = core::array::from_fn(|i| idx[i]);
            assert_eq!(isa.gather(&table, &eight), None);
            let wide: [f64; 40] = table.map(f64::from);
            assert_eq!(isa.gather(&wide, &idx), None);
            // An index out of range: no gather (the caller's read panics, as any slice's).
            let mut bad = idx;
            bad[11] = 40;
            assert_eq!(isa.gather(&table, &bad), None);
        }
    }
}
