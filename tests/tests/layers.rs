//! The crates' layers run one way: no circle among the top-level modules of `shared`,
//! `host-sim` and the firmware, and in host-sim no computation imports figure or command code.
//!
//! An edge `a → b` is a `crate::b` path (or a name in `use crate::{…}`) in a file of module `a`
//! (a file's module is its first path component under `src/`), outside `//` comments and the
//! `#[cfg(test)]` tail of the file.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

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
