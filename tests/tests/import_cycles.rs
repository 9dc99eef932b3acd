//! No import cycle between the files of a crate (issue 27).
//!
//! For every library and binary target of every workspace member (read from `cargo metadata`, so
//! moved or new crates are covered), the module tree is built from the `mod` declarations, and
//! each file's references to other modules are collected: its private `use` items and every path
//! in its code that starts with `crate::`, `super::`, `self::` or the name of a child module. A
//! reference is followed through re-exports (`pub use`) to the module that defines the item, so
//! `use crate::Frame` depends on the file that declares `Frame`, not on `lib.rs`; a re-export is
//! no dependency of the file that makes it.
//!
//! The dependencies are taken between sibling modules, each with everything below it (`log.rs`
//! and the folder `trace/`): a file that uses `crate::trace::asc::Frame` makes `log` depend on
//! `trace`. A module's references to its own ancestors (`super::Context` in a private child file)
//! and a parent's use of its own children are the ordinary shape of a module split into files,
//! not cycles. A strongly connected component of more than one sibling is a cycle; the test names
//! the modules and, for each step, the file, line and path that makes it. Unit-test code
//! (`#[cfg(test)]` items) is left out: a test may use any sibling it checks against.
//!
//! The self-tests at the bottom run the same analysis on small crates written to a temporary
//! folder: one with a cycle must be reported, and one without must not, so the workspace test
//! can fail.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

use syn::visit::Visit;

/// A module of the tree: the file its items are in, its child modules, the names it imports or
/// re-exports (name → path as written in this module), its glob imports, and the items it
/// defines.
#[derive(Default)]
struct Module {
    file: PathBuf,
    children: BTreeSet<String>,
    uses: BTreeMap<String, Vec<String>>,
    globs: Vec<Vec<String>>,
    items: BTreeSet<String>,
}

/// One reference from a file's code: the module it is written in and the path as written.
struct Reference {
    module: Vec<String>,
    path: Vec<String>,
    line: usize,
}

/// A crate's module tree (keyed by the module path below `crate`) and its files' references.
#[derive(Default)]
struct Crate {
    modules: BTreeMap<Vec<String>, Module>,
    references: BTreeMap<PathBuf, Vec<Reference>>,
    errors: Vec<String>,
}

impl Crate {
    /// Parses the tree from a crate root (`lib.rs`, `main.rs`, `src/bin/x.rs`).
    fn load(root: &Path) -> Crate {
        let mut krate = Crate::default();
        let dir = root.parent().unwrap().to_path_buf();
        krate.load_file(root, Vec::new(), dir);
        krate
    }

    /// Parses one file as the module `module`; `dir` is where its child modules' files are.
    fn load_file(&mut self, file: &Path, module: Vec<String>, dir: PathBuf) {
        let text = match std::fs::read_to_string(file) {
            Ok(text) => text,
            Err(e) => return self.errors.push(format!("{}: {e}", file.display())),
        };
        let ast = match syn::parse_file(&text) {
            Ok(ast) => ast,
            Err(e) => return self.errors.push(format!("{}: {e}", file.display())),
        };
        self.references.entry(file.to_path_buf()).or_default();
        self.load_items(file, &ast.items, module, dir);
    }

    fn load_items(&mut self, file: &Path, items: &[syn::Item], module: Vec<String>, dir: PathBuf) {
        self.modules.entry(module.clone()).or_default().file = file.to_path_buf();
        for item in items.iter().filter(|item| !is_test_only(item)) {
            if let Some(name) = item_name(item) {
                self.modules.get_mut(&module).unwrap().items.insert(name);
            }
            match item {
                syn::Item::Mod(m) => {
                    let name = m.ident.to_string();
                    self.modules.get_mut(&module).unwrap().children.insert(name.clone());
                    let mut child = module.clone();
                    child.push(name.clone());
                    match &m.content {
                        Some((_, inner)) => self.load_items(file, inner, child, dir.join(&name)),
                        None => match module_file(&m.attrs, &dir, &name) {
                            Some((child_file, child_dir)) => self.load_file(&child_file, child, child_dir),
                            None => self.errors.push(format!("{}: no file for `mod {name}`", file.display())),
                        },
                    }
                }
                syn::Item::Use(u) => {
                    let mut paths = Vec::new();
                    flatten_use(&u.tree, Vec::new(), &mut paths);
                    let reexport = !matches!(u.vis, syn::Visibility::Inherited);
                    let line = u.use_token.span.start().line;
                    for (path, name) in paths {
                        let entry = self.modules.get_mut(&module).unwrap();
                        match name {
                            Some(name) => {
                                entry.uses.insert(name, path.clone());
                            }
                            None => entry.globs.push(path.clone()),
                        }
                        if !reexport {
                            self.reference(file, &module, path, line);
                        }
                    }
                }
                other => {
                    let mut paths = Paths::default();
                    paths.visit_item(other);
                    for (path, line) in paths.0 {
                        self.reference(file, &module, path, line);
                    }
                }
            }
        }
    }

    fn reference(&mut self, file: &Path, module: &[String], path: Vec<String>, line: usize) {
        let r = Reference { module: module.to_vec(), path, line };
        self.references.entry(file.to_path_buf()).or_default().push(r);
    }

    /// The path below `crate` that `path`, written in `module`, names; `None` for a path into
    /// another crate (its first segment is neither `crate`, `self`, `super` nor a child module).
    /// Called once the whole tree is loaded, so children declared after a `use` are known.
    fn absolute(&self, module: &[String], path: &[String]) -> Option<Vec<String>> {
        let first = path.first()?.as_str();
        let mut base = module.to_vec();
        let mut rest = path;
        match first {
            "crate" => {
                base.clear();
                rest = &path[1..];
            }
            "self" => rest = &path[1..],
            "super" => {
                while rest.first().map(String::as_str) == Some("super") {
                    base.pop()?;
                    rest = &rest[1..];
                }
            }
            child if self.modules.get(module)?.children.contains(child) => {}
            _ => return None,
        }
        Some([base.as_slice(), rest].concat())
    }

    /// The module whose file defines what `path` (below `crate`) names, following re-exports.
    fn locate(&self, path: &[String], depth: usize) -> Option<Vec<String>> {
        if depth > 16 {
            return None;
        }
        let mut current: Vec<String> = Vec::new();
        for (i, segment) in path.iter().enumerate() {
            let module = self.modules.get(&current)?;
            if module.children.contains(segment) {
                current.push(segment.clone());
                continue;
            }
            if module.items.contains(segment) {
                return Some(current);
            }
            if let Some(written) = module.uses.get(segment) {
                // `None`: another crate's item.
                let target = self.absolute(&current, written)?;
                let rest = &path[i + 1..];
                return self.locate(&[target.as_slice(), rest].concat(), depth + 1);
            }
            for written in &module.globs {
                let Some(glob) = self.absolute(&current, written) else { continue };
                let names = |m: &Module| {
                    m.children.contains(segment) || m.items.contains(segment) || m.uses.contains_key(segment)
                };
                if self.modules.get(&glob).is_some_and(names) {
                    return self.locate(&[glob.as_slice(), &path[i..]].concat(), depth + 1);
                }
            }
            return Some(current);
        }
        Some(current)
    }

    /// The module that defines what `reference` names, if it is in this crate.
    fn resolve(&self, reference: &Reference) -> Option<Vec<String>> {
        let absolute = self.absolute(&reference.module, &reference.path)?;
        self.locate(&absolute, 0)
    }

    /// The dependencies between sibling modules, each taken with everything below it: module →
    /// (sibling it depends on → the first reference to it: file, line and path). A reference
    /// between a module and one of its own ancestors (`super::`, or a parent using its private
    /// child) is no edge, and neither is one between inline modules of one file.
    fn graph(&self, show: &dyn Fn(&Path) -> String) -> Graph {
        let mut graph = Graph::new();
        for (file, references) in &self.references {
            for reference in references {
                let Some(target) = self.resolve(reference) else { continue };
                let common = reference.module.iter().zip(&target).take_while(|(a, b)| a == b).count();
                if common == reference.module.len() || common == target.len() {
                    continue;
                }
                let from = reference.module[..=common].to_vec();
                let to = target[..=common].to_vec();
                if self.modules[&from].file == self.modules[&to].file {
                    continue;
                }
                let target_file = show(&self.modules[&target].file);
                let how = format!(
                    "{} line {}: {} (in {target_file})",
                    show(file),
                    reference.line,
                    reference.path.join("::")
                );
                graph.entry(from).or_default().entry(to).or_insert(how);
            }
        }
        graph
    }
}

/// Module → (sibling module it depends on → how).
type Graph = BTreeMap<Vec<String>, BTreeMap<Vec<String>, String>>;

/// Whether an item is compiled for unit tests only (`#[cfg(test)]`): test code may use any
/// sibling it checks against, so it makes no dependency.
fn is_test_only(item: &syn::Item) -> bool {
    let attrs: &[syn::Attribute] = match item {
        syn::Item::Mod(i) => &i.attrs,
        syn::Item::Fn(i) => &i.attrs,
        syn::Item::Use(i) => &i.attrs,
        syn::Item::Impl(i) => &i.attrs,
        syn::Item::Const(i) => &i.attrs,
        syn::Item::Static(i) => &i.attrs,
        syn::Item::Struct(i) => &i.attrs,
        syn::Item::Enum(i) => &i.attrs,
        _ => return false,
    };
    attrs.iter().any(|a| {
        a.path().is_ident("cfg") && a.meta.require_list().is_ok_and(|l| l.tokens.to_string() == "test")
    })
}

/// The name an item defines in its module's namespace, if any.
fn item_name(item: &syn::Item) -> Option<String> {
    let ident = match item {
        syn::Item::Const(i) => &i.ident,
        syn::Item::Enum(i) => &i.ident,
        syn::Item::Fn(i) => &i.sig.ident,
        syn::Item::Macro(i) => i.ident.as_ref()?,
        syn::Item::Static(i) => &i.ident,
        syn::Item::Struct(i) => &i.ident,
        syn::Item::Trait(i) => &i.ident,
        syn::Item::TraitAlias(i) => &i.ident,
        syn::Item::Type(i) => &i.ident,
        syn::Item::Union(i) => &i.ident,
        _ => return None,
    };
    Some(ident.to_string())
}

/// The file of `mod name;` declared in a file whose children live in `dir`, and the folder of
/// that module's own children; `#[path = "…"]` is honoured.
fn module_file(attrs: &[syn::Attribute], dir: &Path, name: &str) -> Option<(PathBuf, PathBuf)> {
    for attr in attrs {
        if attr.path().is_ident("path") {
            if let syn::Meta::NameValue(nv) = &attr.meta {
                if let syn::Expr::Lit(syn::ExprLit { lit: syn::Lit::Str(s), .. }) = &nv.value {
                    let file = dir.join(s.value());
                    let child_dir = file.parent()?.to_path_buf();
                    return Some((file, child_dir));
                }
            }
        }
    }
    let flat = dir.join(format!("{name}.rs"));
    if flat.is_file() {
        return Some((flat, dir.join(name)));
    }
    let nested = dir.join(name).join("mod.rs");
    nested.is_file().then(|| (nested, dir.join(name)))
}

/// Every path a `use` tree imports: the path and the name it binds (`None` for a glob).
fn flatten_use(tree: &syn::UseTree, prefix: Vec<String>, out: &mut Vec<(Vec<String>, Option<String>)>) {
    let with = |s: String| [prefix.clone(), vec![s]].concat();
    match tree {
        syn::UseTree::Path(p) => flatten_use(&p.tree, with(p.ident.to_string()), out),
        syn::UseTree::Name(n) if n.ident == "self" => {
            let name = prefix.last().cloned();
            out.push((prefix.clone(), name));
        }
        syn::UseTree::Name(n) => out.push((with(n.ident.to_string()), Some(n.ident.to_string()))),
        syn::UseTree::Rename(r) => out.push((with(r.ident.to_string()), Some(r.rename.to_string()))),
        syn::UseTree::Glob(_) => out.push((prefix.clone(), None)),
        syn::UseTree::Group(g) => g.items.iter().for_each(|t| flatten_use(t, prefix.clone(), out)),
    }
}

/// The paths of more than one segment in an item (types, expressions, patterns, trait bounds);
/// nested modules are walked by `Crate::load_items`, not here.
#[derive(Default)]
struct Paths(Vec<(Vec<String>, usize)>);

impl<'ast> Visit<'ast> for Paths {
    fn visit_path(&mut self, path: &'ast syn::Path) {
        if path.segments.len() > 1 && path.leading_colon.is_none() {
            let segments = path.segments.iter().map(|s| s.ident.to_string()).collect();
            let line = path.segments[0].ident.span().start().line;
            self.0.push((segments, line));
        }
        syn::visit::visit_path(self, path);
    }

    fn visit_item_mod(&mut self, _: &'ast syn::ItemMod) {}
}

/// The strongly connected components of more than one module (Tarjan), each sorted.
fn cycles(graph: &Graph) -> Vec<Vec<Vec<String>>> {
    struct State<'g> {
        graph: &'g Graph,
        index: BTreeMap<&'g Vec<String>, usize>,
        low: BTreeMap<&'g Vec<String>, usize>,
        stack: Vec<&'g Vec<String>>,
        on_stack: BTreeSet<&'g Vec<String>>,
        found: Vec<Vec<Vec<String>>>,
    }
    fn connect<'g>(s: &mut State<'g>, v: &'g Vec<String>) {
        let n = s.index.len();
        s.index.insert(v, n);
        s.low.insert(v, n);
        s.stack.push(v);
        s.on_stack.insert(v);
        for w in s.graph.get(v).into_iter().flat_map(|e| e.keys()) {
            if !s.index.contains_key(w) {
                connect(s, w);
                let low = s.low[v].min(s.low[w]);
                s.low.insert(v, low);
            } else if s.on_stack.contains(w) {
                let low = s.low[v].min(s.index[w]);
                s.low.insert(v, low);
            }
        }
        if s.low[v] == s.index[v] {
            let mut component = Vec::new();
            while let Some(w) = s.stack.pop() {
                s.on_stack.remove(w);
                component.push(w.clone());
                if w == v {
                    break;
                }
            }
            if component.len() > 1 {
                component.sort();
                s.found.push(component);
            }
        }
    }
    let mut state = State {
        graph,
        index: BTreeMap::new(),
        low: BTreeMap::new(),
        stack: Vec::new(),
        on_stack: BTreeSet::new(),
        found: Vec::new(),
    };
    for v in graph.keys() {
        if !state.index.contains_key(v) {
            connect(&mut state, v);
        }
    }
    state.found
}

/// The cycles of one crate root, each described as its modules and the references between them
/// (files shown relative to `base`).
fn report(root: &Path, base: &Path) -> Vec<String> {
    let krate = Crate::load(root);
    let mut out: Vec<String> = krate.errors.iter().map(|e| format!("cannot read: {e}")).collect();
    let show = |p: &Path| p.strip_prefix(base).unwrap_or(p).display().to_string();
    let graph = krate.graph(&show);
    let name = |m: &Vec<String>| format!("crate::{}", m.join("::"));
    for component in cycles(&graph) {
        let members: BTreeSet<&Vec<String>> = component.iter().collect();
        let names: Vec<String> = component.iter().map(name).collect();
        let mut text = format!("cycle between {}:", names.join(", "));
        for from in &component {
            for (to, how) in &graph[from] {
                if members.contains(to) {
                    text.push_str(&format!("\n    {} -> {}: {how}", name(from), name(to)));
                }
            }
        }
        out.push(text);
    }
    out
}

/// The workspace's root folder and the library and binary roots of every member. The workspace
/// is this one, or the one whose `Cargo.toml` `IMPORT_CYCLES_MANIFEST` names (to check another
/// tree with this test).
fn workspace_roots() -> (PathBuf, Vec<(String, PathBuf)>) {
    let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".into());
    let manifest = std::env::var("IMPORT_CYCLES_MANIFEST")
        .unwrap_or_else(|_| concat!(env!("CARGO_MANIFEST_DIR"), "/../Cargo.toml").into());
    let output = std::process::Command::new(cargo)
        .args(["metadata", "--no-deps", "--format-version", "1", "--offline", "--manifest-path", &manifest])
        .output()
        .expect("cargo metadata runs");
    assert!(output.status.success(), "cargo metadata: {}", String::from_utf8_lossy(&output.stderr));
    let metadata: serde_json::Value = serde_json::from_slice(&output.stdout).unwrap();
    let members: BTreeSet<&str> =
        metadata["workspace_members"].as_array().unwrap().iter().filter_map(|m| m.as_str()).collect();
    let workspace = PathBuf::from(metadata["workspace_root"].as_str().unwrap());
    let mut roots = Vec::new();
    for package in metadata["packages"].as_array().unwrap() {
        if !members.contains(package["id"].as_str().unwrap()) {
            continue;
        }
        for target in package["targets"].as_array().unwrap() {
            let kinds: Vec<&str> =
                target["kind"].as_array().unwrap().iter().filter_map(|k| k.as_str()).collect();
            if kinds.iter().any(|k| ["lib", "rlib", "bin", "proc-macro", "staticlib", "cdylib"].contains(k)) {
                let name =
                    format!("{} ({})", package["name"].as_str().unwrap(), target["name"].as_str().unwrap());
                roots.push((name, PathBuf::from(target["src_path"].as_str().unwrap())));
            }
        }
    }
    (workspace, roots)
}

#[test]
fn no_import_cycle_between_the_files_of_any_workspace_crate() {
    let (base, roots) = workspace_roots();
    assert!(roots.len() >= 10, "only {} crate roots found: {roots:?}", roots.len());
    let mut failures = Vec::new();
    for (name, root) in &roots {
        for problem in report(root, &base) {
            failures.push(format!("{name}: {problem}"));
        }
    }
    assert!(
        failures.is_empty(),
        "{} import cycle(s) or unreadable files:\n{}",
        failures.len(),
        failures.join("\n")
    );
}

/// Writes `files` (path → text) under a fresh temporary folder and returns its `src/lib.rs`.
fn fixture(name: &str, files: &[(&str, &str)]) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("dnet-import-cycles-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    for (path, text) in files {
        let path = dir.join(path);
        std::fs::create_dir_all(path.parent().unwrap()).unwrap();
        std::fs::write(path, text).unwrap();
    }
    dir.join("src/lib.rs")
}

#[test]
fn a_cycle_between_a_file_and_a_folder_module_is_reported() {
    let root = fixture(
        "cycle",
        &[
            ("src/lib.rs", "mod log;\nmod trace;\npub use trace::Frame;\n"),
            ("src/log.rs", "use crate::trace::read;\npub fn write() { read(); }\n"),
            ("src/trace/mod.rs", "mod asc;\npub use asc::Frame;\npub fn read() {}\n"),
            ("src/trace/asc.rs", "pub struct Frame;\nfn f() { crate::log::write(); }\n"),
        ],
    );
    let problems = report(&root, root.parent().unwrap());
    assert_eq!(problems.len(), 1, "{problems:?}");
    let problem = &problems[0];
    assert!(problem.starts_with("cycle between crate::log, crate::trace:"), "{problem}");
    assert!(
        problem.contains("crate::log -> crate::trace: log.rs line 1: crate::trace::read (in trace/mod.rs)"),
        "{problem}"
    );
    assert!(
        problem.contains("crate::trace -> crate::log: trace/asc.rs line 2: crate::log::write (in log.rs)"),
        "{problem}"
    );
}

#[test]
fn a_cycle_through_a_reexport_and_a_glob_is_reported() {
    let root = fixture(
        "reexport",
        &[
            ("src/lib.rs", "mod a;\nmod b;\npub use b::*;\n"),
            ("src/a.rs", "pub struct A;\nuse crate::B;\n"),
            ("src/b/mod.rs", "mod inner;\npub use self::inner::B;\n"),
            ("src/b/inner.rs", "pub struct B(super::super::a::A);\n"),
        ],
    );
    let problems = report(&root, root.parent().unwrap());
    assert_eq!(problems.len(), 1, "{problems:?}");
    assert!(
        problems[0].contains("crate::a -> crate::b: a.rs line 2: crate::B (in b/inner.rs)"),
        "{problems:?}"
    );
}

#[test]
fn references_to_ancestors_and_reexports_are_no_cycle() {
    let root = fixture(
        "clean",
        &[
            (
                "src/lib.rs",
                "mod frame;\nmod bus;\npub use frame::Frame;\npub use bus::Bus;\npub struct Error;\n",
            ),
            ("src/frame.rs", "pub struct Frame;\n#[cfg(test)]\nmod tests { use crate::bus::f; }\n"),
            (
                "src/bus/mod.rs",
                "mod sim;\npub use sim::Bus;\nuse crate::Frame;\npub fn f(_: Frame) { sim::g() }\n",
            ),
            ("src/bus/sim.rs", "pub struct Bus(crate::Frame, crate::Error);\nuse super::f;\npub fn g() {}\n"),
        ],
    );
    let problems = report(&root, root.parent().unwrap());
    assert!(problems.is_empty(), "{problems:?}");
}
