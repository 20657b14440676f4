//! Output files that appear whole or not at all: every file is written to a temporary file in
//! the target's folder and renamed into place only when the command has succeeded. A target
//! that is a symbolic link to a file is written through the link (the file it names is
//! replaced, the link stays); one that is not a file (`/dev/stdout`, a named pipe, a device)
//! is written to at the end from a temporary file elsewhere, since it cannot be replaced.

use std::path::{Path, PathBuf};

use anyhow::{Context, Result};
use tempfile::NamedTempFile;

/// Pending output files, committed together.
#[derive(Debug, Default)]
pub struct Outputs {
    pending: Vec<(NamedTempFile, Place)>,
}

/// Where an output goes at the end.
#[derive(Debug, Clone, PartialEq)]
enum Place {
    /// Renamed onto this file (the target, or the file its link names).
    Rename(PathBuf),
    /// Copied into this path, opened for writing (not a file: a pipe, a device, a link to one,
    /// or a link to nothing yet).
    WriteInto(PathBuf),
}

impl Place {
    fn of(target: &Path) -> Place {
        let link = std::fs::symlink_metadata(target).is_ok_and(|m| m.file_type().is_symlink());
        match std::fs::metadata(target) {
            Ok(m) if m.is_file() && link => Place::Rename(
                std::fs::canonicalize(target).unwrap_or_else(|_| target.to_path_buf()),
            ),
            Ok(m) if m.is_file() || m.is_dir() => Place::Rename(target.to_path_buf()),
            Ok(_) => Place::WriteInto(target.to_path_buf()),
            Err(_) if link => Place::WriteInto(target.to_path_buf()),
            Err(_) => Place::Rename(target.to_path_buf()),
        }
    }
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
        self.pending.push((tmp, Place::of(target)));
        Ok(path)
    }

    /// Renames every reserved file into place (or writes it into a target that is not a file).
    ///
    /// # Errors
    /// A rename or the write failed.
    pub fn commit(self) -> Result<()> {
        for (tmp, place) in self.pending {
            match place {
                Place::Rename(target) => {
                    tmp.persist(&target).with_context(|| {
                        format!("cannot move the output into {}", target.display())
                    })?;
                }
                Place::WriteInto(target) => {
                    let mut from = std::fs::File::open(tmp.path())?;
                    let mut into = std::fs::File::create(&target)
                        .with_context(|| format!("cannot write {}", target.display()))?;
                    std::io::copy(&mut from, &mut into)
                        .with_context(|| format!("cannot write {}", target.display()))?;
                }
            }
        }
        Ok(())
    }
}

/// `n` of `noun` as the commands say it: `count(1, "point")` is `1 point`, `count(451,
/// "point")` `451 points` (nouns whose plural adds an `s`).
pub fn count(n: u64, noun: &str) -> String {
    count_as(n, noun, &format!("{noun}s"))
}

/// `n` of a noun given in the singular `one` and the plural `many`: `count_as(1, "frequency",
/// "frequencies")` is `1 frequency`, with 51 `51 frequencies`.
pub fn count_as(n: u64, one: &str, many: &str) -> String {
    format!("{n} {}", if n == 1 { one } else { many })
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
    let dir = match Place::of(target) {
        // Not renamed onto its target: the system's temporary folder.
        Place::WriteInto(_) => std::env::temp_dir(),
        Place::Rename(t) => match t.parent() {
            Some(d) if !d.as_os_str().is_empty() => d.to_path_buf(),
            _ => PathBuf::from("."),
        },
    };
    let mut builder = tempfile::Builder::new();
    builder.prefix(".host-sim-").suffix(suffix);
    // Outputs are ordinary files (rw-r--r--), not the temporary file's private 0600.
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt;
        builder.permissions(std::fs::Permissions::from_mode(0o644));
    }
    let file = builder.tempfile_in(&dir).with_context(|| {
        format!(
            "cannot write {} (folder {})",
            target.display(),
            dir.display()
        )
    })?;
    crate::interrupt::temporary(file.path().to_path_buf());
    Ok(file)
}

/// The command line's parser of an output file (`--out`): a file name (not empty, not a
/// folder) whose folder exists and takes a file, checked when the command line is read, before
/// any work.
///
/// # Errors
/// No file name, or the folder is missing or not writable (said with the path).
pub fn out_target(text: &str) -> Result<PathBuf, String> {
    let path = PathBuf::from(text);
    if text.is_empty() || text.ends_with('/') || path.is_dir() {
        return Err(format!("`{text}` is not a file name: give a file to write"));
    }
    // A temporary file made and removed at once: what the output will need.
    scratch(&path, ".check")
        .map(drop)
        .map_err(|e| format!("{e:#}"))?;
    Ok(path)
}

/// The command line's parser of a figure (`--plot` and the like): a name ending in `.png` or
/// `.svg` (any case; the format the figure is drawn in, `figures::Backend::for_path`) in a
/// folder that takes a file ([`out_target`]).
///
/// # Errors
/// Another extension, or as [`out_target`].
pub fn figure_target(text: &str) -> Result<PathBuf, String> {
    let path = PathBuf::from(text);
    if !path
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("png") || e.eq_ignore_ascii_case("svg"))
    {
        return Err(
            "figures are drawn as PNG or SVG: give a file name ending in .png or .svg".into(),
        );
    }
    out_target(text)
}

/// The flags of `flags` that were given, with their paths (for [`distinct_files`]).
pub fn given<'a>(flags: &[(&'a str, Option<&'a Path>)]) -> Vec<(&'a str, &'a Path)> {
    flags
        .iter()
        .filter_map(|&(flag, p)| p.map(|p| (flag, p)))
        .collect()
}

/// Checks that no output (a flag and its path) is one of the `inputs` or another output: it
/// would replace the data being read, or the other result.
///
/// # Errors
/// Two of them name the same file (both flags and the path said).
pub fn distinct_files(inputs: &[(&str, &Path)], outputs: &[(&str, &Path)]) -> Result<()> {
    // The file a path names: its canonical form, or its folder's with its name if it does
    // not exist yet.
    let identity = |p: &Path| {
        std::fs::canonicalize(p).unwrap_or_else(|_| {
            let dir = p.parent().filter(|d| !d.as_os_str().is_empty());
            let dir = dir.map_or_else(|| std::fs::canonicalize("."), std::fs::canonicalize);
            match (dir, p.file_name()) {
                (Ok(d), Some(n)) => d.join(n),
                _ => p.to_path_buf(),
            }
        })
    };
    for (k, (flag, out)) in outputs.iter().enumerate() {
        let id = identity(out);
        for (other, path) in inputs.iter().chain(&outputs[..k]) {
            anyhow::ensure!(
                identity(path) != id,
                "{flag} {} is also {other}: it would replace it; give another file",
                out.display()
            );
        }
    }
    Ok(())
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

#[cfg(all(test, unix))]
mod tests {
    use super::*;

    fn write_text(target: &Path, text: &str) -> Result<()> {
        write_whole(target, |tmp| Ok(std::fs::write(tmp, text)?))
    }

    /// Through a link to a file: the file is replaced, the link stays a link. Through a link to
    /// nothing: the file it names is created. Into a named pipe: the reader gets the bytes and
    /// the pipe stays a pipe. No temporary file is left beside any of them.
    #[test]
    fn an_output_may_not_be_an_input_or_another_output() {
        let dir = tempfile::tempdir().unwrap();
        let data = dir.path().join("d.csv");
        std::fs::write(&data, "t_s,force_n\n").unwrap();
        let out = dir.path().join("fit.toml");
        let plot = dir.path().join("fit.png");
        let ins = [("--trace", data.as_path())];
        assert!(distinct_files(&ins, &[("--out", &out), ("--plot", &plot)]).is_ok());
        // The same file under another spelling.
        let again = dir.path().join(".").join("d.csv");
        let e = distinct_files(&ins, &[("--out", &again)]).unwrap_err();
        assert!(e.to_string().contains("is also --trace"), "{e}");
        let e = distinct_files(&ins, &[("--out", &plot), ("--plot", &plot)]).unwrap_err();
        assert!(e.to_string().starts_with("--plot"), "{e}");
    }

    #[test]
    fn links_and_pipes_are_written_through() {
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path();
        std::fs::write(d.join("file.csv"), "old").unwrap();
        std::os::unix::fs::symlink(d.join("file.csv"), d.join("link.csv")).unwrap();
        write_text(&d.join("link.csv"), "new").unwrap();
        assert!(
            std::fs::symlink_metadata(d.join("link.csv"))
                .unwrap()
                .file_type()
                .is_symlink()
        );
        assert_eq!(std::fs::read_to_string(d.join("file.csv")).unwrap(), "new");

        std::os::unix::fs::symlink(d.join("later.csv"), d.join("dangling.csv")).unwrap();
        write_text(&d.join("dangling.csv"), "made").unwrap();
        assert_eq!(
            std::fs::read_to_string(d.join("later.csv")).unwrap(),
            "made"
        );

        let fifo = d.join("fifo");
        nix::unistd::mkfifo(&fifo, nix::sys::stat::Mode::S_IRWXU).unwrap();
        let reader = {
            let fifo = fifo.clone();
            std::thread::spawn(move || std::fs::read_to_string(fifo).unwrap())
        };
        write_text(&fifo, "piped").unwrap();
        assert_eq!(reader.join().unwrap(), "piped");
        assert!(std::os::unix::fs::FileTypeExt::is_fifo(
            &std::fs::symlink_metadata(&fifo).unwrap().file_type()
        ));
        let mut names: Vec<String> = std::fs::read_dir(d)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        names.sort();
        assert_eq!(
            names,
            ["dangling.csv", "fifo", "file.csv", "later.csv", "link.csv"]
        );
    }
}
