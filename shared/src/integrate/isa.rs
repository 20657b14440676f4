//! Which vector instructions the host's lane kernels ([`super::lanes`], `contact_lanes`,
//! `switch_lanes`, `near`) run, chosen at run time from what the CPU reports, and the one place
//! that compiles a kernel for each ([`Kernel`], [`Isa::run`]).
//!
//! The variants compile the same source with more instructions enabled: the same operations
//! in the same order and no fused multiply-add (Rust never contracts `a * b + c`), so every
//! variant gives the same bits. On the MCU (no `std`) the kernels are the portable code.

/// A lane kernel's body with its arguments, run by [`Isa::run`] in the instruction set asked
/// for. Implementations mark [`Kernel::run`] `#[inline(always)]` (and whatever it calls that
/// should vectorise), so that the body compiles into each variant.
pub(crate) trait Kernel {
    /// What the kernel returns.
    type Output;
    /// The body.
    fn run(self) -> Self::Output;
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
        let widest = Self::widest();
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
            Isa::Portable => kernel.run(),
        }
    }

    /// The widest variant the CPU reports.
    fn widest() -> Isa {
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

/// [`Kernel::run`] compiled for AVX-512.
#[cfg(all(feature = "std", target_arch = "x86_64"))]
#[target_feature(enable = "avx,avx2,avx512f,avx512vl,avx512dq,avx512bw")]
fn run_avx512<K: Kernel>(kernel: K) -> K::Output {
    kernel.run()
}

/// [`Kernel::run`] compiled for AVX2.
#[cfg(all(feature = "std", target_arch = "x86_64"))]
#[target_feature(enable = "avx,avx2")]
fn run_avx2<K: Kernel>(kernel: K) -> K::Output {
    kernel.run()
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
}
