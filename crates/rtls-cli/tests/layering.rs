//! No import cycles between files (`../shared/STYLE.md`: "No file imports another that imports
//! it back; a circle means a type lives in the wrong file").
//!
//! The checker parses every `.rs` file under `crates/*/src` with `syn` and maps each file to its
//! module path by following the `mod` declarations from the crate roots (`lib.rs`, `main.rs`,
//! `bin/*.rs`): `mod foo;` is `foo.rs` or `foo/mod.rs` beside or below its parent as rustc finds
//! it, `#[path = "…"]` is honoured, inline `mod foo { … }` blocks are modules of their file.
//!
//! An edge "file A uses an item from file B" comes from every `crate::…`, `super::…`, `self::…`
//! path in A — in `use` items and in code (types, expressions, patterns, trait bounds, macro
//! arguments), never in comments, doc comments or strings — and from paths through a module
//! brought in by `use` (`use super::kf; … kf::Item`). B is the file of the deepest module the
//! path names (`crate::tracker::update::accept` → the file of `tracker::update`). Re-exports are
//! not chased: `crate::site::Reader` is an edge to the file of `site` even where that file
//! re-exports `keys::Reader`.
//!
//! Not edges: a module file's uses of its own descendants (`mod x;` makes `x` part of its
//! parent, so a facade's `pub use x::Item` is containment, not an import), visibility paths
//! (`pub(in crate::a)`), and everything compiled only for tests: `#[cfg(test)]` items and
//! modules, `mod tests`, and files named `tests*.rs`, `*_tests.rs` or `test_support.rs`.
//!
//! The strongly connected components (Tarjan) of more than one file are the cycles; each is
//! reported with its files, each file's edges into the cycle (`src/a.rs:LINE uses crate::x::Y ->
//! src/x.rs`) and one shortest loop through it.

use std::collections::{BTreeMap, BTreeSet, HashMap, VecDeque};
use std::fmt::Write as _;
use std::io::Write as _;
use std::path::{Path, PathBuf};

use proc_macro2::{Spacing, TokenStream, TokenTree};
use syn::visit::{self, Visit};

/// Crates whose cycles are printed, not failed on.
///
/// Empty since issue 18 removed the last cycles (rtls-engine's tracker and radio map); a crate
/// listed here while a large refactoring is under way has its cycles printed instead. Every
/// other crate under `crates/` must have none.
const PENDING_CRATES: &[&str] = &[];

/// A module path from the crate root: `[]` is the root, `["tracker", "update"]` is
/// `crate::tracker::update`.
type ModPath = Vec<String>;

/// One crate's source files: path relative to the crate directory (`src/lib.rs`) → text.
type Sources = BTreeMap<String, String>;

/// Where a file uses a module of another file: the first such path in the file.
#[derive(Clone, Debug, PartialEq, Eq)]
struct Use {
    line: usize,
    /// the path as written, `use` groups flattened: `crate::site::Reader`, `super::*`
    path: String,
}

/// A set of files that reach each other through their uses.
#[derive(Debug)]
struct Cycle {
    /// the files, sorted
    files: Vec<String>,
    /// every edge between two files of the cycle: (from, to, the first use)
    edges: Vec<(String, String, Use)>,
    /// one shortest loop through the first file, ending where it starts
    shortest_loop: Vec<String>,
}

/// What the checker finds in one crate.
#[derive(Debug, Default)]
struct Analysis {
    /// every file in the graph → its module path
    modules: BTreeMap<String, ModPath>,
    /// (from, to) → the first use; containment and self edges left out
    edges: BTreeMap<(String, String), Use>,
    cycles: Vec<Cycle>,
    /// `.rs` files under `src` that no crate root reaches and that are not test files
    unreached: Vec<String>,
}

// ---------------------------------------------------------------------------------------------
// The module tree

/// One crate root's modules.
#[derive(Default)]
struct ModuleTree {
    /// every module, inline ones too → the file it lives in
    modules: BTreeMap<ModPath, String>,
    /// every module file → its module path and syntax tree
    files: BTreeMap<String, (ModPath, syn::File)>,
    /// the files of test modules, left out
    test_files: BTreeSet<String>,
}

fn join(dir: &str, name: &str) -> String {
    if dir.is_empty() {
        name.to_string()
    } else {
        format!("{dir}/{name}")
    }
}

fn parent_dir(file: &str) -> String {
    file.rsplit_once('/').map_or(String::new(), |(dir, _)| dir.to_string())
}

/// `a/./b/../c.rs` → `a/c.rs`.
fn normalise(path: &str) -> String {
    let mut parts: Vec<&str> = Vec::new();
    for part in path.split('/') {
        match part {
            "" | "." => {}
            ".." => {
                parts.pop();
            }
            _ => parts.push(part),
        }
    }
    parts.join("/")
}

/// Files that hold only test code by their name: `tests*.rs`, `*_tests.rs`, `test_support.rs`.
fn is_test_file_name(name: &str) -> bool {
    name.strip_suffix(".rs")
        .is_some_and(|stem| stem.starts_with("tests") || stem.ends_with("_tests") || stem == "test_support")
}

/// A test file by name, or a file below a `tests` directory (the children of `tests.rs`).
fn is_test_path(path: &str) -> bool {
    let mut parts = path.split('/').peekable();
    while let Some(part) = parts.next() {
        if parts.peek().is_some() {
            if part == "tests" {
                return true;
            }
        } else {
            return is_test_file_name(part);
        }
    }
    false
}

/// `#[cfg(test)]` or `#[cfg(all(test, …))]`: compiled for tests only.
fn has_cfg_test(attrs: &[syn::Attribute]) -> bool {
    attrs.iter().any(|attr| {
        if !attr.path().is_ident("cfg") {
            return false;
        }
        let syn::Meta::List(list) = &attr.meta else {
            return false;
        };
        cfg_is_test(list.tokens.clone())
    })
}

fn cfg_is_test(tokens: TokenStream) -> bool {
    let tokens: Vec<TokenTree> = tokens.into_iter().collect();
    match tokens.as_slice() {
        [TokenTree::Ident(ident)] => ident == "test",
        [TokenTree::Ident(all), TokenTree::Group(group)] if all == "all" => group
            .stream()
            .into_iter()
            .collect::<Vec<_>>()
            .split(|t| matches!(t, TokenTree::Punct(p) if p.as_char() == ','))
            .any(|term| matches!(term, [TokenTree::Ident(ident)] if ident == "test")),
        _ => false,
    }
}

fn is_test_module(module: &syn::ItemMod) -> bool {
    module.ident == "tests" || has_cfg_test(&module.attrs)
}

/// The value of a `#[path = "…"]` attribute.
fn path_attribute(attrs: &[syn::Attribute]) -> Option<String> {
    attrs.iter().find_map(|attr| match &attr.meta {
        syn::Meta::NameValue(nv) if nv.path.is_ident("path") => match &nv.value {
            syn::Expr::Lit(syn::ExprLit {
                lit: syn::Lit::Str(s), ..
            }) => Some(s.value()),
            _ => None,
        },
        _ => None,
    })
}

impl ModuleTree {
    /// Follows the `mod` declarations from `root` (`src/lib.rs`, `src/main.rs`, …).
    fn load(sources: &Sources, root: &str) -> Result<Self, String> {
        let mut tree = Self::default();
        let mut queue = vec![(root.to_string(), ModPath::new(), true)];
        while let Some((file, module, mod_rs)) = queue.pop() {
            let text = sources
                .get(&file)
                .ok_or_else(|| format!("{file}: declared by a `mod` item but not found"))?;
            let ast = syn::parse_file(text).map_err(|e| {
                let at = e.span().start();
                format!("{file}:{}:{}: {e}", at.line, at.column + 1)
            })?;
            let dir = parent_dir(&file);
            // rustc: the children of `lib.rs`, `main.rs`, `mod.rs` and `#[path]` files live
            // beside them; those of `foo.rs` in `foo/`
            let child_dir = if mod_rs {
                dir.clone()
            } else {
                let stem = file.rsplit('/').next().unwrap_or(&file);
                join(&dir, stem.trim_end_matches(".rs"))
            };
            tree.modules.insert(module.clone(), file.clone());
            tree.declare(sources, &file, &ast.items, &module, &child_dir, &dir, &mut queue);
            tree.files.insert(file, (module, ast));
        }
        Ok(tree)
    }

    /// Registers the modules declared by `items` (in `file`, module `module`) and queues the
    /// files of the out-of-line ones.
    #[allow(clippy::too_many_arguments)]
    fn declare(
        &mut self,
        sources: &Sources,
        file: &str,
        items: &[syn::Item],
        module: &ModPath,
        child_dir: &str,
        path_base: &str,
        queue: &mut Vec<(String, ModPath, bool)>,
    ) {
        for item in items {
            let syn::Item::Mod(declared) = item else {
                continue;
            };
            let name = declared.ident.to_string();
            let mut child = module.clone();
            child.push(name.clone());
            let path = path_attribute(&declared.attrs);
            let test = is_test_module(declared);
            match &declared.content {
                Some(_) if test => {}
                Some((_, inner)) => {
                    self.modules.insert(child.clone(), file.to_string());
                    let inner_dir = normalise(&join(child_dir, path.as_deref().unwrap_or(&name)));
                    self.declare(sources, file, inner, &child, &inner_dir, &inner_dir, queue);
                }
                None => {
                    let (child_file, mod_rs) = match path {
                        Some(path) => (normalise(&join(path_base, &path)), true),
                        None => {
                            let flat = join(child_dir, &format!("{name}.rs"));
                            if sources.contains_key(&flat) {
                                (flat, false)
                            } else {
                                (join(child_dir, &format!("{name}/mod.rs")), true)
                            }
                        }
                    };
                    let file_name = child_file.rsplit('/').next().unwrap_or(&child_file);
                    if test || is_test_file_name(file_name) {
                        self.test_files.insert(child_file);
                    } else {
                        queue.push((child_file, child, mod_rs));
                    }
                }
            }
        }
    }

    /// The deepest module that `segments` (as written in module `scope`) names, and whether it
    /// names that module itself rather than an item in it. `None` for paths that do not start
    /// in this crate.
    fn resolve(
        &self,
        scope: &ModPath,
        segments: &[String],
        aliases: &HashMap<(ModPath, String), ModPath>,
    ) -> Option<(ModPath, bool)> {
        let first = segments.first()?;
        let (mut full, rest) = match first.as_str() {
            "crate" => (ModPath::new(), 1),
            "self" => (scope.clone(), 1),
            "super" => {
                let mut base = scope.clone();
                let mut n = 0;
                while segments.get(n).is_some_and(|s| s == "super") {
                    base.pop()?;
                    n += 1;
                }
                (base, n)
            }
            name => (aliases.get(&(scope.clone(), name.to_string()))?.clone(), 1),
        };
        full.extend(segments[rest..].iter().cloned());
        (0..=full.len()).rev().find_map(|n| {
            self.modules
                .contains_key(&full[..n])
                .then(|| (full[..n].to_vec(), n == full.len()))
        })
    }
}

// ---------------------------------------------------------------------------------------------
// The paths a file writes

/// A path written in a file, before resolution.
struct Written {
    /// the module it is written in (inline modules included)
    scope: ModPath,
    segments: Vec<String>,
    line: usize,
    /// `use a::b::*`
    glob: bool,
    /// the name a `use` brings into scope (`kf` for `use super::kf;`)
    binds: Option<String>,
}

/// Collects the paths of one file, leaving out test-only code.
struct Collector {
    scope: ModPath,
    written: Vec<Written>,
}

fn line_of(ident: &proc_macro2::Ident) -> usize {
    ident.span().start().line
}

fn item_attrs(item: &syn::Item) -> &[syn::Attribute] {
    use syn::Item;
    match item {
        Item::Const(i) => &i.attrs,
        Item::Enum(i) => &i.attrs,
        Item::ExternCrate(i) => &i.attrs,
        Item::Fn(i) => &i.attrs,
        Item::ForeignMod(i) => &i.attrs,
        Item::Impl(i) => &i.attrs,
        Item::Macro(i) => &i.attrs,
        Item::Mod(i) => &i.attrs,
        Item::Static(i) => &i.attrs,
        Item::Struct(i) => &i.attrs,
        Item::Trait(i) => &i.attrs,
        Item::TraitAlias(i) => &i.attrs,
        Item::Type(i) => &i.attrs,
        Item::Union(i) => &i.attrs,
        Item::Use(i) => &i.attrs,
        _ => &[],
    }
}

impl Collector {
    fn record(&mut self, segments: Vec<String>, line: usize, glob: bool, binds: Option<String>) {
        self.written.push(Written {
            scope: self.scope.clone(),
            segments,
            line,
            glob,
            binds,
        });
    }

    /// Flattens a `use` tree: `use crate::a::{b::C, self as d, e::*}` → three paths.
    fn use_tree(&mut self, tree: &syn::UseTree, prefix: &mut Vec<(String, usize)>) {
        let names = |prefix: &[(String, usize)]| prefix.iter().map(|(s, _)| s.clone()).collect();
        match tree {
            syn::UseTree::Path(p) => {
                prefix.push((p.ident.to_string(), line_of(&p.ident)));
                self.use_tree(&p.tree, prefix);
                prefix.pop();
            }
            syn::UseTree::Name(n) if n.ident == "self" => {
                let binds = prefix.last().map(|(s, _)| s.clone());
                self.record(names(prefix), line_of(&n.ident), false, binds);
            }
            syn::UseTree::Name(n) => {
                let mut segments: Vec<String> = names(prefix);
                segments.push(n.ident.to_string());
                self.record(segments, line_of(&n.ident), false, Some(n.ident.to_string()));
            }
            syn::UseTree::Rename(r) => {
                let mut segments: Vec<String> = names(prefix);
                if r.ident != "self" {
                    segments.push(r.ident.to_string());
                }
                let binds = Some(r.rename.to_string());
                self.record(segments, line_of(&r.ident), false, binds);
            }
            syn::UseTree::Glob(g) => {
                let line = g.star_token.spans[0].start().line;
                self.record(names(prefix), line, true, None);
            }
            syn::UseTree::Group(g) => {
                for tree in &g.items {
                    self.use_tree(tree, prefix);
                }
            }
        }
    }

    /// Paths in a macro's tokens (`assert!(crate::a::f())`, `$crate::x::Y`): every
    /// `ident :: ident …` run that is not the tail of a longer path. String literals are single
    /// tokens, so their text is never read.
    fn tokens(&mut self, tokens: TokenStream) {
        let tokens: Vec<TokenTree> = tokens.into_iter().collect();
        let colon2 = |i: usize| {
            matches!(
                (tokens.get(i), tokens.get(i + 1)),
                (Some(TokenTree::Punct(a)), Some(TokenTree::Punct(b)))
                    if a.as_char() == ':' && a.spacing() == Spacing::Joint && b.as_char() == ':'
            )
        };
        let mut i = 0;
        while i < tokens.len() {
            match &tokens[i] {
                TokenTree::Group(group) => {
                    self.tokens(group.stream());
                    i += 1;
                }
                TokenTree::Ident(first) if !(i >= 2 && colon2(i - 2)) => {
                    let mut segments = vec![first.to_string()];
                    let mut j = i + 1;
                    while colon2(j) {
                        let Some(TokenTree::Ident(next)) = tokens.get(j + 2) else {
                            break;
                        };
                        segments.push(next.to_string());
                        j += 3;
                    }
                    if segments.len() >= 2 {
                        self.record(segments, line_of(first), false, None);
                    }
                    i = j;
                }
                _ => i += 1,
            }
        }
    }
}

impl<'ast> Visit<'ast> for Collector {
    fn visit_item(&mut self, item: &'ast syn::Item) {
        if has_cfg_test(item_attrs(item)) {
            return;
        }
        match item {
            syn::Item::Mod(module) => {
                if is_test_module(module) {
                    return;
                }
                if let Some((_, items)) = &module.content {
                    self.scope.push(module.ident.to_string());
                    for item in items {
                        self.visit_item(item);
                    }
                    self.scope.pop();
                }
            }
            syn::Item::Use(u) => {
                if u.leading_colon.is_none() {
                    self.use_tree(&u.tree, &mut Vec::new());
                }
            }
            _ => visit::visit_item(self, item),
        }
    }

    fn visit_impl_item(&mut self, item: &'ast syn::ImplItem) {
        let attrs: &[syn::Attribute] = match item {
            syn::ImplItem::Const(i) => &i.attrs,
            syn::ImplItem::Fn(i) => &i.attrs,
            syn::ImplItem::Type(i) => &i.attrs,
            syn::ImplItem::Macro(i) => &i.attrs,
            _ => &[],
        };
        if !has_cfg_test(attrs) {
            visit::visit_impl_item(self, item);
        }
    }

    fn visit_trait_item(&mut self, item: &'ast syn::TraitItem) {
        let attrs: &[syn::Attribute] = match item {
            syn::TraitItem::Const(i) => &i.attrs,
            syn::TraitItem::Fn(i) => &i.attrs,
            syn::TraitItem::Type(i) => &i.attrs,
            syn::TraitItem::Macro(i) => &i.attrs,
            _ => &[],
        };
        if !has_cfg_test(attrs) {
            visit::visit_trait_item(self, item);
        }
    }

    // doc comments are attributes, and `pub(in crate::a)` says who may use an item, not what
    // it uses
    fn visit_attribute(&mut self, _: &'ast syn::Attribute) {}
    fn visit_visibility(&mut self, _: &'ast syn::Visibility) {}

    fn visit_path(&mut self, path: &'ast syn::Path) {
        if path.leading_colon.is_none() && path.segments.len() >= 2 {
            let segments = path.segments.iter().map(|s| s.ident.to_string()).collect();
            self.record(segments, line_of(&path.segments[0].ident), false, None);
        }
        visit::visit_path(self, path);
    }

    fn visit_macro(&mut self, mac: &'ast syn::Macro) {
        visit::visit_macro(self, mac);
        self.tokens(mac.tokens.clone());
    }
}

// ---------------------------------------------------------------------------------------------
// The graph and its cycles

/// Tarjan's strongly connected components of `graph` (node → successors), each sorted.
fn strongly_connected(graph: &BTreeMap<String, BTreeSet<String>>) -> Vec<Vec<String>> {
    struct State<'g> {
        graph: &'g BTreeMap<String, BTreeSet<String>>,
        index: HashMap<&'g str, usize>,
        low: HashMap<&'g str, usize>,
        stack: Vec<&'g str>,
        on_stack: BTreeSet<&'g str>,
        components: Vec<Vec<String>>,
    }
    fn connect<'g>(s: &mut State<'g>, v: &'g str) {
        let n = s.index.len();
        s.index.insert(v, n);
        s.low.insert(v, n);
        s.stack.push(v);
        s.on_stack.insert(v);
        for w in s.graph.get(v).into_iter().flatten() {
            let w = w.as_str();
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
                component.push(w.to_string());
                if w == v {
                    break;
                }
            }
            component.sort();
            s.components.push(component);
        }
    }
    let mut s = State {
        graph,
        index: HashMap::new(),
        low: HashMap::new(),
        stack: Vec::new(),
        on_stack: BTreeSet::new(),
        components: Vec::new(),
    };
    for v in graph.keys() {
        if !s.index.contains_key(v.as_str()) {
            connect(&mut s, v);
        }
    }
    s.components
}

/// A shortest loop from `start` back to it inside `members` (breadth first).
fn shortest_loop(graph: &BTreeMap<String, BTreeSet<String>>, members: &BTreeSet<&str>, start: &str) -> Vec<String> {
    let mut came_from: HashMap<&str, &str> = HashMap::new();
    let mut queue = VecDeque::from([start]);
    while let Some(v) = queue.pop_front() {
        for w in graph.get(v).into_iter().flatten() {
            let w = w.as_str();
            if !members.contains(w) {
                continue;
            }
            if w == start {
                let mut path = vec![start.to_string()];
                let mut at = v;
                while at != start {
                    path.push(at.to_string());
                    at = came_from[at];
                }
                path.push(start.to_string());
                path.reverse();
                return path;
            }
            if !came_from.contains_key(w) {
                came_from.insert(w, v);
                queue.push_back(w);
            }
        }
    }
    Vec::new()
}

/// The crate roots among `sources`: `src/lib.rs`, `src/main.rs`, `src/bin/*.rs`,
/// `src/bin/*/main.rs`.
fn crate_roots(sources: &Sources) -> Vec<&str> {
    sources
        .keys()
        .map(String::as_str)
        .filter(|path| {
            matches!(*path, "src/lib.rs" | "src/main.rs")
                || path
                    .strip_prefix("src/bin/")
                    .is_some_and(|rest| !rest.contains('/') || rest.split('/').nth(1) == Some("main.rs"))
        })
        .collect()
}

/// The file-level use graph of one crate and its cycles.
fn analyse(sources: &Sources) -> Result<Analysis, String> {
    let mut analysis = Analysis::default();
    let mut test_files = BTreeSet::new();
    for root in crate_roots(sources) {
        let tree = ModuleTree::load(sources, root)?;
        test_files.extend(tree.test_files.iter().cloned());
        for (file, (module, ast)) in &tree.files {
            analysis.modules.insert(file.clone(), module.clone());
            let mut collector = Collector {
                scope: module.clone(),
                written: Vec::new(),
            };
            for item in &ast.items {
                collector.visit_item(item);
            }
            // modules brought into scope by `use` (`use super::kf;`), in the order written
            let mut aliases = HashMap::new();
            for w in &collector.written {
                if let Some(name) = &w.binds {
                    if let Some((target, true)) = tree.resolve(&w.scope, &w.segments, &aliases) {
                        aliases.insert((w.scope.clone(), name.clone()), target);
                    }
                }
            }
            for w in &collector.written {
                let Some((target, _)) = tree.resolve(&w.scope, &w.segments, &aliases) else {
                    continue;
                };
                let target_file = &tree.modules[&target];
                let target_module = &tree.files[target_file].0;
                // the file itself, or one of its own descendants (containment)
                if target_module.starts_with(module) {
                    continue;
                }
                let mut path = w.segments.join("::");
                if w.glob {
                    path.push_str("::*");
                }
                let found = Use { line: w.line, path };
                analysis
                    .edges
                    .entry((file.clone(), target_file.clone()))
                    .and_modify(|first| {
                        if found.line < first.line {
                            *first = found.clone();
                        }
                    })
                    .or_insert(found);
            }
        }
    }
    analysis.unreached = sources
        .keys()
        .filter(|path| !analysis.modules.contains_key(*path) && !test_files.contains(*path) && !is_test_path(path))
        .cloned()
        .collect();

    let mut graph: BTreeMap<String, BTreeSet<String>> = analysis
        .modules
        .keys()
        .map(|file| (file.clone(), BTreeSet::new()))
        .collect();
    for (from, to) in analysis.edges.keys() {
        graph.entry(from.clone()).or_default().insert(to.clone());
    }
    let mut components: Vec<Vec<String>> = strongly_connected(&graph)
        .into_iter()
        .filter(|component| component.len() > 1)
        .collect();
    components.sort();
    for files in components {
        let members: BTreeSet<&str> = files.iter().map(String::as_str).collect();
        let edges = analysis
            .edges
            .iter()
            .filter(|((from, to), _)| members.contains(from.as_str()) && members.contains(to.as_str()))
            .map(|((from, to), found)| (from.clone(), to.clone(), found.clone()))
            .collect();
        let shortest_loop = shortest_loop(&graph, &members, &files[0]);
        analysis.cycles.push(Cycle {
            files,
            edges,
            shortest_loop,
        });
    }
    Ok(analysis)
}

/// The cycles of one crate, for people.
fn report(crate_name: &str, cycles: &[Cycle]) -> String {
    let mut out = String::new();
    for (n, cycle) in cycles.iter().enumerate() {
        let _ = writeln!(
            out,
            "{crate_name}: cycle {} of {}: {} files",
            n + 1,
            cycles.len(),
            cycle.files.len()
        );
        for file in &cycle.files {
            let _ = writeln!(out, "  {file}");
            let mut edges: Vec<_> = cycle.edges.iter().filter(|(from, ..)| from == file).collect();
            edges.sort_by_key(|(.., found)| found.line);
            for (from, to, found) in edges {
                let _ = writeln!(out, "    {from}:{} uses {} -> {to}", found.line, found.path);
            }
        }
        let _ = writeln!(out, "  shortest loop: {}", cycle.shortest_loop.join(" -> "));
    }
    out
}

// ---------------------------------------------------------------------------------------------
// The workspace

/// Every `.rs` file under `dir`, keyed by its path relative to `crate_dir` with `/`.
fn read_sources(crate_dir: &Path, dir: &Path, sources: &mut Sources) {
    let mut entries: Vec<PathBuf> = std::fs::read_dir(dir)
        .unwrap_or_else(|e| panic!("{}: {e}", dir.display()))
        .map(|entry| entry.expect("a directory entry").path())
        .collect();
    entries.sort();
    for path in entries {
        if path.is_dir() {
            read_sources(crate_dir, &path, sources);
        } else if path.extension().is_some_and(|ext| ext == "rs") {
            let relative = path.strip_prefix(crate_dir).expect("below the crate");
            let key = relative
                .components()
                .map(|c| c.as_os_str().to_string_lossy())
                .collect::<Vec<_>>()
                .join("/");
            let text = std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
            sources.insert(key, text);
        }
    }
}

/// The crates under `crates/` that have a `src` directory: name → directory.
fn workspace_crates() -> BTreeMap<String, PathBuf> {
    let crates_dir = Path::new(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .expect("crates/rtls-cli is inside crates/");
    std::fs::read_dir(crates_dir)
        .expect("crates/ is readable")
        .map(|entry| entry.expect("a directory entry").path())
        .filter(|dir| dir.join("src").is_dir())
        .map(|dir| {
            let name = dir.file_name().unwrap().to_string_lossy().into_owned();
            (name, dir)
        })
        .collect()
}

#[test]
fn no_file_imports_a_file_that_imports_it_back() {
    let crates = workspace_crates();
    for pending in PENDING_CRATES {
        assert!(
            crates.contains_key(*pending),
            "PENDING_CRATES names {pending}, which is not a crate under crates/"
        );
    }
    let mut failures = String::new();
    let mut stderr = std::io::stderr();
    for (name, dir) in &crates {
        let mut sources = Sources::new();
        read_sources(dir, &dir.join("src"), &mut sources);
        let analysis = analyse(&sources).unwrap_or_else(|e| panic!("{name}: {e}"));
        for file in &analysis.unreached {
            println!("note: {name}/{file} is reached from no crate root (not compiled)");
        }
        let cycles = report(name, &analysis.cycles);
        println!(
            "{name}: {} files, {} edges between files, {} cycles",
            analysis.modules.len(),
            analysis.edges.len(),
            analysis.cycles.len()
        );
        if PENDING_CRATES.contains(&name.as_str()) {
            print!("{cycles}");
            // past the test harness's capture, so that every run shows what is pending
            let _ = if analysis.cycles.is_empty() {
                writeln!(
                    stderr,
                    "layering: {name} has no file import cycle left: take it off PENDING_CRATES"
                )
            } else {
                writeln!(
                    stderr,
                    "layering: {name} has {} file import cycles, pending (issue 18); \
                     `cargo test -p rtls-cli --test layering -- --nocapture` lists them",
                    analysis.cycles.len()
                )
            };
        } else {
            failures.push_str(&cycles);
        }
    }
    assert!(
        failures.is_empty(),
        "files that import a file that imports them back (STYLE.md: a circle means a type \
         lives in the wrong file; move the shared items to a file both can import):\n{failures}"
    );
}

// ---------------------------------------------------------------------------------------------
// The checker's own tests, on small synthetic crates

fn crate_of(files: &[(&str, &str)]) -> Analysis {
    let sources = files
        .iter()
        .map(|(path, text)| (path.to_string(), text.to_string()))
        .collect();
    analyse(&sources).expect("the synthetic crate parses")
}

fn edge(analysis: &Analysis, from: &str, to: &str) -> Option<Use> {
    analysis.edges.get(&(from.to_string(), to.to_string())).cloned()
}

#[test]
fn a_cycle_between_two_files_is_found_with_its_lines() {
    let analysis = crate_of(&[
        ("src/lib.rs", "pub mod kf;\npub mod ekf;\n"),
        ("src/kf.rs", "//! KF\nuse crate::ekf::Linearised;\npub struct Kf;\n"),
        (
            "src/ekf.rs",
            "pub struct Linearised;\n\nfn f() -> super::kf::Kf { super::kf::Kf }\n",
        ),
    ]);
    assert_eq!(analysis.cycles.len(), 1);
    let cycle = &analysis.cycles[0];
    assert_eq!(cycle.files, ["src/ekf.rs", "src/kf.rs"]);
    assert_eq!(cycle.shortest_loop, ["src/ekf.rs", "src/kf.rs", "src/ekf.rs"]);
    let text = report("demo", &analysis.cycles);
    assert!(
        text.contains("src/kf.rs:2 uses crate::ekf::Linearised -> src/ekf.rs"),
        "{text}"
    );
    assert!(text.contains("src/ekf.rs:3 uses super::kf::Kf -> src/kf.rs"), "{text}");
}

#[test]
fn a_three_file_cycle_is_one_component() {
    let analysis = crate_of(&[
        ("src/lib.rs", "mod mqtt;\n"),
        ("src/mqtt/mod.rs", "mod broker;\nmod connection;\nmod session;\n"),
        (
            "src/mqtt/broker.rs",
            "use super::connection::Connection;\npub struct Broker;\n",
        ),
        (
            "src/mqtt/connection.rs",
            "pub struct Connection(super::session::Session);\n",
        ),
        (
            "src/mqtt/session.rs",
            "pub struct Session;\nfn f(_: &crate::mqtt::broker::Broker) {}\n",
        ),
    ]);
    assert_eq!(analysis.cycles.len(), 1);
    assert_eq!(
        analysis.cycles[0].files,
        ["src/mqtt/broker.rs", "src/mqtt/connection.rs", "src/mqtt/session.rs"]
    );
    assert_eq!(analysis.cycles[0].shortest_loop.len(), 4);
}

#[test]
fn containment_and_re_exports_are_not_cycles() {
    // site/mod.rs declares and re-exports keys.rs; keys.rs uses site/mod.rs's `Site` and its
    // own `Reader` through the re-export
    let analysis = crate_of(&[
        ("src/lib.rs", "pub mod site;\npub use site::{Reader, Site};\n"),
        (
            "src/site/mod.rs",
            "mod keys;\npub use keys::Reader;\npub use self::keys::Key;\n\
             pub struct Site(pub Vec<keys::Reader>);\n",
        ),
        (
            "src/site/keys.rs",
            "use super::Site;\npub struct Key;\npub struct Reader;\n\
             fn f(_: crate::site::Reader, _: &crate::Site) {}\n",
        ),
    ]);
    assert!(analysis.cycles.is_empty(), "{:?}", analysis.cycles);
    assert_eq!(
        edge(&analysis, "src/site/keys.rs", "src/site/mod.rs"),
        Some(Use {
            line: 1,
            path: "super::Site".into()
        })
    );
    assert!(edge(&analysis, "src/site/keys.rs", "src/lib.rs").is_some());
    assert!(edge(&analysis, "src/site/mod.rs", "src/site/keys.rs").is_none());
    assert!(edge(&analysis, "src/lib.rs", "src/site/mod.rs").is_none());
}

#[test]
fn comments_doc_comments_strings_and_visibilities_are_not_uses() {
    let analysis = crate_of(&[
        ("src/lib.rs", "mod a;\nmod b;\n"),
        ("src/a.rs", "use crate::b::B;\npub struct A;\n"),
        (
            "src/b.rs",
            "//! See [`crate::a::A`].\n\
             /// Like [crate::a::A].\n\
             pub(in crate::a) struct B;\n\
             // crate::a::A\n\
             /* super::a::A */\n\
             const S: &str = \"crate::a::A\";\n\
             fn f() { println!(\"{}\", \"super::a::A\"); }\n",
        ),
    ]);
    assert!(analysis.cycles.is_empty(), "{:?}", analysis.cycles);
    assert!(edge(&analysis, "src/b.rs", "src/a.rs").is_none());
}

#[test]
fn test_code_is_not_in_the_graph() {
    let analysis = crate_of(&[
        ("src/lib.rs", "mod a;\nmod b;\n#[cfg(test)]\nmod test_support;\n"),
        ("src/a.rs", "use crate::b::B;\npub struct A;\n"),
        (
            "src/b.rs",
            "pub struct B;\n\
             #[cfg(test)]\nuse crate::a::A;\n\
             #[cfg(all(test, feature = \"x\"))]\nfn g(_: crate::a::A) {}\n\
             impl B {\n    #[cfg(test)]\n    fn h(_: crate::a::A) {}\n}\n\
             #[cfg(test)]\n#[path = \"b_tests.rs\"]\nmod more;\n\
             #[cfg(test)]\n#[path = \"b_3d.rs\"]\nmod three_d;\n\
             mod tests {\n    use super::super::a::A;\n}\n",
        ),
        ("src/b_tests.rs", "use crate::a::A;\n"),
        ("src/b_3d.rs", "use crate::a::A;\n"),
        ("src/b/tests.rs", "use crate::a::A;\n"),
        ("src/test_support.rs", "use crate::a::A;\n"),
    ]);
    assert!(analysis.cycles.is_empty(), "{:?}", analysis.cycles);
    assert!(edge(&analysis, "src/b.rs", "src/a.rs").is_none());
    assert_eq!(
        analysis.modules.keys().collect::<Vec<_>>(),
        ["src/a.rs", "src/b.rs", "src/lib.rs"]
    );
    assert!(analysis.unreached.is_empty(), "{:?}", analysis.unreached);
    // `not(test)` is compiled outside tests
    let analysis = crate_of(&[
        ("src/lib.rs", "mod a;\nmod b;\n"),
        ("src/a.rs", "use crate::b::B;\npub struct A;\n"),
        ("src/b.rs", "pub struct B;\n#[cfg(not(test))]\nuse crate::a::A;\n"),
    ]);
    assert_eq!(analysis.cycles.len(), 1);
}

#[test]
fn paths_resolve_to_the_deepest_module_file() {
    let analysis = crate_of(&[
        ("src/lib.rs", "pub mod tracker;\npub mod site;\npub mod zones;\n"),
        (
            "src/tracker.rs",
            "pub mod update;\n#[path = \"tracker/solver_impl.rs\"]\npub mod solve;\n",
        ),
        ("src/tracker/update.rs", "pub fn accept() {}\n"),
        ("src/tracker/solver_impl.rs", "pub mod inner;\n"),
        ("src/tracker/inner.rs", "pub fn solve() {}\n"),
        (
            "src/site/mod.rs",
            "pub struct Site;\npub mod nested { pub struct N; }\n",
        ),
        (
            "src/zones.rs",
            "fn f() {\n    crate::tracker::update::accept();\n    let _ = crate::site::Site;\n    \
             let _ = crate::site::nested::N;\n    crate::tracker::solve::inner::solve();\n}\n",
        ),
    ]);
    assert_eq!(analysis.modules["src/tracker/inner.rs"], ["tracker", "solve", "inner"]);
    let update = edge(&analysis, "src/zones.rs", "src/tracker/update.rs").unwrap();
    assert_eq!(
        (update.line, update.path.as_str()),
        (2, "crate::tracker::update::accept")
    );
    assert_eq!(edge(&analysis, "src/zones.rs", "src/site/mod.rs").unwrap().line, 3);
    assert!(edge(&analysis, "src/zones.rs", "src/tracker/inner.rs").is_some());
    assert!(edge(&analysis, "src/zones.rs", "src/tracker.rs").is_none());
}

#[test]
fn macro_arguments_and_module_aliases_are_uses() {
    let analysis = crate_of(&[
        ("src/lib.rs", "mod a;\nmod b;\nmod c;\n"),
        ("src/a.rs", "use super::b;\npub fn f() -> bool {\n    b::g()\n}\n"),
        (
            "src/b.rs",
            "pub fn g() -> bool {\n    true\n}\nfn h() {\n    assert!(crate::a::f());\n}\n",
        ),
        (
            "src/c.rs",
            "use crate::{a as alias, b::{self}};\nfn k() {\n    let _ = vec![alias::f(), b::g()];\n}\n",
        ),
    ]);
    assert_eq!(analysis.cycles.len(), 1);
    assert_eq!(analysis.cycles[0].files, ["src/a.rs", "src/b.rs"]);
    assert_eq!(
        edge(&analysis, "src/b.rs", "src/a.rs"),
        Some(Use {
            line: 5,
            path: "crate::a::f".into()
        })
    );
    assert_eq!(edge(&analysis, "src/a.rs", "src/b.rs").unwrap().line, 1);
    assert!(edge(&analysis, "src/c.rs", "src/a.rs").is_some());
}

#[test]
fn binaries_are_their_own_crates() {
    let analysis = crate_of(&[
        ("src/main.rs", "mod cli;\nmod plot;\n"),
        ("src/cli.rs", "use crate::plot::Plot;\npub struct Cli;\n"),
        ("src/plot.rs", "pub struct Plot;\n"),
        ("src/bin/tool/main.rs", "mod util;\nfn main() {}\n"),
        ("src/bin/tool/util.rs", "pub fn u() {}\n"),
        ("src/orphan.rs", "pub fn o() {}\n"),
    ]);
    assert!(analysis.cycles.is_empty());
    assert!(edge(&analysis, "src/cli.rs", "src/plot.rs").is_some());
    assert_eq!(analysis.modules["src/bin/tool/util.rs"], ["util"]);
    assert_eq!(analysis.unreached, ["src/orphan.rs"]);
}
