//! The crates' layers run one way: no circle among the top-level modules of `shared`,
//! `host-sim` and the firmware, nor among the files of any module folder (`integrate/stepper.rs`,
//! `integrate/near.rs`, …), and in host-sim no computation imports figure or command code.
//!
//! An edge `a → b` between top-level modules is a `crate::b` path (or a name in
//! `use crate::{…}`) in a file of module `a` (a file's module is its first path component under
//! `src/`), outside `//` comments and the `#[cfg(test)]` tail of the file. Between the files of
//! one folder, an edge is a `crate::…` or `super::…` path that leads into a sibling, a name the
//! folder's `mod.rs` re-exports (`pub use stepper::Simulator`) counting as its file's.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};
use std::sync::LazyLock;

use regex::Regex;

type Graph = BTreeMap<String, BTreeSet<String>>;

fn rust_files(dir: &Path, out: &mut Vec<PathBuf>) {
    for e in std::fs::read_dir(dir).unwrap() {
        let p = e.unwrap().path();
        if p.is_dir() {
            rust_files(&p, out);
        } else if p.extension().is_some_and(|x| x == "rs") {
            out.push(p);
        }
    }
}

/// The module graph of one crate's `src/`.
fn graph(src: &Path) -> Graph {
    let path_re = regex::Regex::new(r"crate::(\w+)").unwrap();
    let group_re = regex::Regex::new(r"use crate::\{([^}]*)\}").unwrap();
    let name_re = regex::Regex::new(r"(?:^|,)\s*(\w+)").unwrap();
    let comment_re = regex::Regex::new(r"//[^\n]*").unwrap();
    let mut files = Vec::new();
    rust_files(src, &mut files);
    let mut g = Graph::new();
    for f in files {
        let rel = f.strip_prefix(src).unwrap();
        let first = rel
            .components()
            .next()
            .unwrap()
            .as_os_str()
            .to_string_lossy();
        let module = first.trim_end_matches(".rs").to_string();
        if module == "lib" || module == "main" {
            continue;
        }
        let text = std::fs::read_to_string(&f).unwrap();
        let code = text.split("#[cfg(test)]").next().unwrap_or("");
        let code = comment_re.replace_all(code, "");
        let edges = g.entry(module.clone()).or_default();
        for c in path_re.captures_iter(&code) {
            edges.insert(c[1].to_string());
        }
        for c in group_re.captures_iter(&code) {
            for n in name_re.captures_iter(&c[1]) {
                edges.insert(n[1].to_string());
            }
        }
        edges.remove(&module);
    }
    g
}

/// Modules of `g` that reach themselves (each circle's members).
fn circles(g: &Graph) -> Vec<String> {
    let reach = |from: &str| {
        let mut seen = BTreeSet::new();
        let mut todo: Vec<&str> = g
            .get(from)
            .map_or(vec![], |e| e.iter().map(String::as_str).collect());
        while let Some(m) = todo.pop() {
            if seen.insert(m.to_string()) {
                todo.extend(g.get(m).into_iter().flatten().map(String::as_str));
            }
        }
        seen
    };
    g.keys()
        .filter(|m| reach(m).contains(*m))
        .cloned()
        .collect()
}

fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}

#[test]
fn no_crate_has_an_import_circle() {
    for krate in ["shared", "host-sim", "firmware"] {
        let g = graph(&root().join(krate).join("src"));
        assert!(g.len() >= 3, "{krate}: too few modules read ({g:?})");
        let c = circles(&g);
        assert!(
            c.is_empty(),
            "{krate}: modules in an import circle: {c:?}\n{g:#?}"
        );
    }
}

/// A `//` comment to its line's end.
static COMMENT: LazyLock<Regex> = LazyLock::new(|| Regex::new(r"//[^\n]*").unwrap());

/// A module's path under `src/` (`["integrate", "near"]`; the crate root `[]`).
type ModPath = Vec<String>;

/// Every module file of one crate's `src/`: its module path and its code (outside `//` comments
/// and the `#[cfg(test)]` tail). `mod.rs` is its folder's module; `src/bin/` holds other crates.
fn module_files(src: &Path) -> BTreeMap<ModPath, String> {
    let mut files = Vec::new();
    rust_files(src, &mut files);
    let mut out = BTreeMap::new();
    for f in files {
        let rel = f.strip_prefix(src).unwrap().with_extension("");
        let mut path: ModPath = rel
            .components()
            .map(|c| c.as_os_str().to_string_lossy().into_owned())
            .collect();
        if path.first().is_some_and(|p| p == "bin") {
            continue;
        }
        if path.last().is_some_and(|l| l == "mod")
            || (path.len() == 1 && ["lib", "main"].contains(&path[0].as_str()))
        {
            path.pop();
        }
        let text = std::fs::read_to_string(&f).unwrap();
        let code = text.split("#[cfg(test)]").next().unwrap_or("");
        out.insert(path, COMMENT.replace_all(code, "").into_owned());
    }
    out
}

/// The names a folder module's file re-exports from its children (`pub use stepper::{Simulator,
/// StepCounts}` → `Simulator → stepper`, `StepCounts → stepper`).
fn reexports(code: &str) -> BTreeMap<String, String> {
    static USE: LazyLock<Regex> = LazyLock::new(|| {
        Regex::new(r"pub(?:\([^)]*\))?\s+use\s+(?:self::)?(\w+)::([^;]*);").unwrap()
    });
    static NAME: LazyLock<Regex> = LazyLock::new(|| Regex::new(r"(\w+)\s*(?:,|\}|$)").unwrap());
    let mut out = BTreeMap::new();
    for u in USE.captures_iter(code) {
        for n in NAME.captures_iter(&u[2]) {
            out.insert(n[1].to_string(), u[1].to_string());
        }
    }
    out
}

/// The module a path of names leads to from the crate root: the deepest module file on it, or,
/// where the next name is one its folder's `mod.rs` re-exports (`exports`), that name's child.
fn resolve(
    names: &[String],
    mods: &BTreeMap<ModPath, String>,
    exports: &BTreeMap<ModPath, BTreeMap<String, String>>,
) -> Option<ModPath> {
    let n = (0..=names.len())
        .rev()
        .find(|&n| mods.contains_key(&names[..n]))?;
    let mut found = names[..n].to_vec();
    if let Some(child) = names.get(n).and_then(|next| exports[&found].get(next)) {
        found.push(child.clone());
        if !mods.contains_key(&found) {
            found.pop();
        }
    }
    Some(found)
}

/// The paths a module's code names, from the crate root: `crate::a::b…`, `super::…` (relative
/// to the module), and each name of a `{…}` group after either.
fn named_paths(module: &ModPath, code: &str) -> Vec<Vec<String>> {
    static PATH: LazyLock<Regex> = LazyLock::new(|| {
        Regex::new(r"(?-u:\b)(crate|super)((?:::(?-u:\w)+)*)(::\{[^}]*\})?").unwrap()
    });
    static NAME: LazyLock<Regex> = LazyLock::new(|| Regex::new(r"(?:^|[{,])\s*(\w+)").unwrap());
    // `super` of a file is its folder; of a folder's `mod.rs`, the folder's parent.
    let parent = module[..module.len() - 1].to_vec();
    let mut out = Vec::new();
    for c in PATH.captures_iter(code) {
        let mut base = if &c[1] == "crate" {
            vec![]
        } else {
            parent.clone()
        };
        let mut rest: Vec<String> = c[2]
            .split("::")
            .filter(|s| !s.is_empty())
            .map(String::from)
            .collect();
        // `super::super::x`
        while rest.first().is_some_and(|r| r == "super") {
            rest.remove(0);
            base.pop();
        }
        base.extend(rest);
        match c.get(3) {
            Some(group) => {
                for n in NAME.captures_iter(group.as_str().trim_start_matches("::")) {
                    let mut p = base.clone();
                    p.push(n[1].to_string());
                    out.push(p);
                }
            }
            None => out.push(base),
        }
    }
    out
}

/// For every folder of one crate's `src/` (the crate root included), the graph of its children
/// (files and sub-folders, by name): `a → b` where code in `a` (or under it) names `b` (or
/// something under it, or a name the folder re-exports from it).
fn folder_graphs(src: &Path) -> BTreeMap<ModPath, Graph> {
    let mods = module_files(src);
    let exports: BTreeMap<ModPath, BTreeMap<String, String>> = mods
        .iter()
        .map(|(m, code)| (m.clone(), reexports(code)))
        .collect();
    let mut out: BTreeMap<ModPath, Graph> = BTreeMap::new();
    for (module, code) in &mods {
        if module.is_empty() {
            continue;
        }
        for path in named_paths(module, code) {
            let Some(target) = resolve(&path, &mods, &exports) else {
                continue;
            };
            let common = module
                .iter()
                .zip(&target)
                .take_while(|(a, b)| a == b)
                .count();
            if common < module.len() && common < target.len() {
                out.entry(module[..common].to_vec())
                    .or_default()
                    .entry(module[common].clone())
                    .or_default()
                    .insert(target[common].clone());
            }
        }
    }
    out
}

/// File-level circles allowed (none: any circle fails).
const KNOWN_CIRCLES: &[(&str, &str, &[&str])] = &[];

#[test]
fn no_module_folder_has_a_file_level_import_circle() {
    for krate in ["shared", "host-sim", "firmware"] {
        let graphs = folder_graphs(&root().join(krate).join("src"));
        let files: usize = graphs.values().map(BTreeMap::len).sum();
        assert!(files >= 2, "{krate}: too few files read ({graphs:?})");
        for (folder, g) in &graphs {
            let c = circles(g);
            let name = folder.join("/");
            let known = KNOWN_CIRCLES
                .iter()
                .find(|(k, f, _)| *k == krate && *f == name)
                .is_some_and(|(_, _, members)| c == *members);
            assert!(
                c.is_empty() || known,
                "{krate}/src/{name}: files in an import circle: {c:?}\n{g:#?}"
            );
        }
    }
}

/// The file-level graphs read what the code says: in `integrate/`, the stepper uses the near
/// search, and the lockstep lanes the stepper through a name `mod.rs` re-exports
/// (`super::Simulator`); at the top level, the orbits use the integrator.
#[test]
fn the_folder_graphs_read_real_edges() {
    let graphs = folder_graphs(&root().join("shared/src"));
    let integrate = &graphs[&vec!["integrate".to_string()]];
    assert!(integrate["stepper"].contains("near"), "{integrate:#?}");
    assert!(integrate["lanes"].contains("stepper"), "{integrate:#?}");
    assert!(graphs[&vec![]]["orbit"].contains("integrate"));
}

#[test]
fn host_sim_computations_never_import_figures_or_commands() {
    let g = graph(&root().join("host-sim/src"));
    for (module, deps) in &g {
        if ["commands", "cli"].contains(&module.as_str()) {
            continue;
        }
        assert!(
            !deps.contains("commands") && !deps.contains("cli"),
            "{module} imports commands: {deps:?}"
        );
        if module != "figures" {
            assert!(
                !deps.contains("figures"),
                "{module} imports figure code: {deps:?}"
            );
        }
    }
    // The check reads real edges: the commands use the figures.
    assert!(g["commands"].contains("figures"));
}

#[test]
fn shared_console_is_above_control_and_control_holds_no_text() {
    let g = graph(&root().join("shared/src"));
    assert!(g["console"].contains("control"), "{g:?}");
    assert!(
        !g["control"].contains("console"),
        "control imports console: {g:?}"
    );
}

#[test]
fn the_circle_check_finds_a_circle() {
    let g: Graph = [("a", "b"), ("b", "c"), ("c", "a"), ("d", "a")]
        .into_iter()
        .map(|(x, y)| (x.to_string(), BTreeSet::from([y.to_string()])))
        .collect();
    assert_eq!(circles(&g), ["a", "b", "c"]);
}
