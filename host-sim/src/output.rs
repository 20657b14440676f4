//! Output files that appear whole or not at all: every file is written to a temporary file in
//! the target's folder and renamed into place only when the command has succeeded.

use std::path::{Path, PathBuf};

use anyhow::{Context, Result};
use tempfile::NamedTempFile;

/// Pending output files, committed together.
#[derive(Debug, Default)]
pub struct Outputs {
    pending: Vec<(NamedTempFile, PathBuf)>,
}

impl Outputs {
    /// A new, empty set.
    pub fn new() -> Self {
        Self::default()
    }

    /// Reserves a temporary file for `target` (same folder, same extension) and returns its path.
    ///
    /// # Errors
    /// The folder does not exist or is not writable.
    pub fn reserve(&mut self, target: &Path) -> Result<PathBuf> {
        let suffix = target
            .extension()
            .map(|e| format!(".{}", e.to_string_lossy()))
            .unwrap_or_default();
        let tmp = scratch(target, &suffix)?;
        let path = tmp.path().to_path_buf();
        self.pending.push((tmp, target.to_path_buf()));
        Ok(path)
    }

    /// Renames every reserved file into place.
    ///
    /// # Errors
    /// A rename failed.
    pub fn commit(self) -> Result<()> {
        for (tmp, target) in self.pending {
            tmp.persist(&target)
                .with_context(|| format!("cannot move the output into {}", target.display()))?;
        }
        Ok(())
    }
}

/// Writes one file whole or not at all: `write` fills a temporary file beside `target`
/// (given its path), which then replaces `target`.
///
/// # Errors
/// The folder is not writable, `write` failed, or the rename failed; `target` is untouched then.
pub fn write_whole(target: &Path, write: impl FnOnce(&Path) -> Result<()>) -> Result<()> {
    let mut outputs = Outputs::new();
    let tmp = outputs.reserve(target)?;
    write(&tmp)?;
    outputs.commit()
}

/// A temporary file `.host-sim-…{suffix}` in `target`'s folder (so that renaming it onto
/// `target` stays on one file system), mode `rw-r--r--`, removed when dropped.
///
/// # Errors
/// The folder does not exist or is not writable.
pub fn scratch(target: &Path, suffix: &str) -> Result<NamedTempFile> {
    let dir = match target.parent() {
        Some(d) if !d.as_os_str().is_empty() => d.to_path_buf(),
        _ => PathBuf::from("."),
    };
    let mut builder = tempfile::Builder::new();
    builder.prefix(".host-sim-").suffix(suffix);
    // Outputs are ordinary files (rw-r--r--), not the temporary file's private 0600.
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt;
        builder.permissions(std::fs::Permissions::from_mode(0o644));
    }
    builder.tempfile_in(&dir).with_context(|| {
        format!(
            "cannot write {} (folder {})",
            target.display(),
            dir.display()
        )
    })
}

/// Writes `rows` as CSV (header from the row type) to `path`.
///
/// # Errors
/// I/O or serialisation failure.
pub fn write_csv<R: serde::Serialize>(
    path: &Path,
    rows: impl IntoIterator<Item = R>,
) -> Result<()> {
    let mut w = csv::Writer::from_path(path)
        .with_context(|| format!("cannot create {}", path.display()))?;
    for r in rows {
        w.serialize(r)?;
    }
    w.flush()?;
    Ok(())
}
