//! The documentation's links: every relative link and image in `README.md`, `CHANGELOG.md` and
//! `docs/**/*.md` resolves to a file of the repository (and a `#fragment` to a heading of it),
//! every `docs/….md` page that a source file or page names exists, and nothing points outside
//! the repository (no `../` above its root, no `MODEL.md` or `seed/` of the project's notes).

use std::collections::HashSet;
use std::fs;
use std::path::{Path, PathBuf};

use pulldown_cmark::{Event, Parser, Tag, TagEnd};

fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("..")
        .canonicalize()
        .unwrap()
}

/// The repository's files (not `target/`, not hidden folders), relative to the root.
fn files(dir: &Path, out: &mut Vec<PathBuf>) {
    for e in fs::read_dir(dir).unwrap().filter_map(Result::ok) {
        let p = e.path();
        let name = e.file_name().to_string_lossy().into_owned();
        if name.starts_with('.') || name == "target" {
            continue;
        }
        if p.is_dir() {
            files(&p, out);
        } else {
            out.push(p);
        }
    }
}

/// GitHub's anchor of a heading: lower case, spaces to `-`, punctuation dropped.
fn anchor(text: &str) -> String {
    text.trim()
        .to_lowercase()
        .chars()
        .filter_map(|c| match c {
            ' ' => Some('-'),
            c if c.is_alphanumeric() || c == '-' || c == '_' => Some(c),
            _ => None,
        })
        .collect()
}

/// The anchors of a markdown file's headings.
fn anchors(md: &str) -> HashSet<String> {
    let mut out = HashSet::new();
    let mut heading: Option<String> = None;
    for ev in Parser::new(md) {
        match ev {
            Event::Start(Tag::Heading { .. }) => heading = Some(String::new()),
            Event::Text(t) | Event::Code(t) => {
                if let Some(h) = heading.as_mut() {
                    h.push_str(&t);
                }
            }
            Event::End(TagEnd::Heading(_)) => {
                if let Some(h) = heading.take() {
                    out.insert(anchor(&h));
                }
            }
            _ => {}
        }
    }
    out
}

/// The link and image targets of a markdown file.
fn targets(md: &str) -> Vec<String> {
    Parser::new(md)
        .filter_map(|ev| match ev {
            Event::Start(Tag::Link { dest_url, .. })
            | Event::Start(Tag::Image { dest_url, .. }) => Some(dest_url.into_string()),
            _ => None,
        })
        .collect()
}

#[test]
fn every_relative_link_and_image_resolves() {
    let root = root();
    let mut all = Vec::new();
    files(&root, &mut all);
    let pages: Vec<&PathBuf> = all
        .iter()
        .filter(|p| {
            let rel = p.strip_prefix(&root).unwrap();
            p.extension().is_some_and(|e| e == "md")
                && (rel.starts_with("docs") || rel.parent() == Some(Path::new("")))
        })
        .collect();
    assert!(pages.len() >= 8, "{pages:?}");
    let mut broken = Vec::new();
    for page in &pages {
        let text = fs::read_to_string(page).unwrap();
        for t in targets(&text) {
            if t.contains("://") || t.starts_with("mailto:") {
                continue;
            }
            let (path, fragment) = match t.split_once('#') {
                Some((p, f)) => (p, Some(f)),
                None => (t.as_str(), None),
            };
            let target = if path.is_empty() {
                (*page).clone()
            } else {
                page.parent().unwrap().join(path)
            };
            let Ok(resolved) = target.canonicalize() else {
                broken.push(format!("{}: {t} (no such file)", page.display()));
                continue;
            };
            if !resolved.starts_with(&root) {
                broken.push(format!("{}: {t} (outside the repository)", page.display()));
                continue;
            }
            if let Some(f) = fragment
                && resolved.extension().is_some_and(|e| e == "md")
                && !anchors(&fs::read_to_string(&resolved).unwrap()).contains(f)
            {
                broken.push(format!("{}: {t} (no heading #{f})", page.display()));
            }
        }
    }
    assert!(broken.is_empty(), "broken links:\n{}", broken.join("\n"));
}

#[test]
fn named_pages_exist_and_nothing_points_outside_the_repository() {
    let root = root();
    let mut all = Vec::new();
    files(&root, &mut all);
    let page = regex::Regex::new(r"docs/[A-Za-z0-9_/-]+\.(md|sh|toml|sbatch|png)").unwrap();
    let outside = regex::Regex::new(r"MODEL\.md|\.\./shared/|\bseed/thesis").unwrap();
    let mut bad = Vec::new();
    for f in &all {
        let rel = f.strip_prefix(&root).unwrap();
        let ext = f.extension().and_then(|e| e.to_str()).unwrap_or("");
        if !["rs", "md", "toml", "sh", "sbatch"].contains(&ext)
            || rel.starts_with("tests/tests/all/docs.rs")
        {
            continue;
        }
        let Ok(text) = fs::read_to_string(f) else {
            continue;
        };
        for m in page.find_iter(&text) {
            if !root.join(m.as_str()).exists() {
                bad.push(format!(
                    "{}: names {} (no such file)",
                    rel.display(),
                    m.as_str()
                ));
            }
        }
        for m in outside.find_iter(&text) {
            bad.push(format!(
                "{}: points outside the repository ({})",
                rel.display(),
                m.as_str()
            ));
        }
    }
    assert!(bad.is_empty(), "{}", bad.join("\n"));
}

/// The Markdown pages: docs/ (every level) and README.md.
fn markdown_pages() -> Vec<std::path::PathBuf> {
    let mut pages = Vec::new();
    files(&root().join("docs"), &mut pages);
    pages.push(root().join("README.md"));
    pages.retain(|p| p.extension().is_some_and(|e| e == "md"));
    pages
}

/// Every `--law a|b|…` the documentation writes lists the laws of `ContactLawKind::ALL`, in
/// its order (a law added to the code is one the pages name).
#[test]
fn the_pages_list_every_contact_law() {
    let all = shared::model::ContactLawKind::ALL.map(shared::model::ContactLawKind::name);
    let mut found = 0;
    for page in &markdown_pages() {
        let text = fs::read_to_string(page).unwrap();
        for list in text.split("--law ").skip(1) {
            let word = list.split(|c: char| c.is_whitespace() || c == '`' || c == ',');
            let Some(names) = word.into_iter().next().filter(|w| w.contains('|')) else {
                continue;
            };
            let names: Vec<&str> = names.split('|').collect();
            assert_eq!(
                names,
                all,
                "{}: `--law {}`",
                page.display(),
                names.join("|")
            );
            found += 1;
        }
    }
    assert!(found >= 1, "no `--law a|b|…` list in the pages");
}

/// Every list of the rigs the documentation writes, `--rig a|b|…` and the console's
/// `rig <a\|b\|…>`, names rigs of `RigId::ALL` in its order, and the pages' full lists (the
/// options in README.md and docs/analysis.md, the console's `rig` in docs/operator.md) name every
/// one of them: a rig added to the code is one the pages name. A list of some rigs, an example
/// (`--rig wires|beam-170`), is allowed.
#[test]
fn the_pages_list_every_rig() {
    let all = shared::model::RigId::NAMES;
    let mut full = 0;
    for page in &markdown_pages() {
        let text = fs::read_to_string(page).unwrap().replace("\\|", "|");
        for list in text
            .split("--rig ")
            .skip(1)
            .chain(text.split("rig <").skip(1))
        {
            let word = list.split(|c: char| c.is_whitespace() || "`,>".contains(c));
            let Some(names) = word.into_iter().next().filter(|w| w.contains('|')) else {
                continue;
            };
            let names: Vec<&str> = names.split('|').collect();
            let mut rest = all.iter();
            assert!(
                names.iter().all(|n| rest.any(|r| r == n)),
                "{}: {} are not rigs in the order of RigId::ALL ({})",
                page.display(),
                names.join("|"),
                all.join("|")
            );
            if names == all {
                full += 1;
            }
        }
    }
    assert!(
        full >= 3,
        "the pages' lists of every rig ({}): {full} of 3",
        all.join("|")
    );
}
