//! The modules of src/ import one another without a circle, so each stage can
//! be read, tested and changed on its own (issue 48, item 1). CPU only: it
//! reads the sources and needs neither the crate nor a GPU.
//!
//! Granularity: a node is a top-level module (a folder under src/, or a file
//! directly in it: `solve`, `report`, `config`), plus `lib` for the items
//! lib.rs defines itself (`crate::Baked`, `crate::bake_scene`). Files inside
//! one folder may refer to each other both ways (a child reads its parent's
//! types through `super::`, the parent calls the child): that is one stage's
//! inside. Between stages the arrows must point one way. main.rs is left out:
//! it is another crate, which reaches the library only through `bake::`.
//!
//! An edge is any path, in a `use` or in code, that starts with `crate::`,
//! `super::` (resolved through the file's place and its inline `mod`s), or,
//! in lib.rs, with the name of a top-level module. Comments, strings and
//! character literals are blanked first; doc links are not dependencies.

use std::collections::{BTreeMap, BTreeSet, VecDeque};
use std::path::Path;

/// One place a module refers to another: the file, its line and the path.
#[derive(Clone, Debug)]
struct Reference {
    file: String,
    line: usize,
    path: String,
}

/// from → to → the first reference that makes the edge.
type Graph = BTreeMap<String, BTreeMap<String, Reference>>;

#[test]
fn the_module_graph_has_no_cycle() {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    let mut files = Vec::new();
    collect_sources(&src, &src, &mut files);
    assert!(files.len() > 50, "only {} files under src/: is the walk broken?", files.len());
    let graph = graph(&files);
    // Known edges, so a parser that finds nothing cannot pass quietly.
    for (from, to) in [("lib", "solve"), ("cli", "config"), ("solve", "gpu"), ("check", "report")] {
        assert!(graph.get(from).is_some_and(|e| e.contains_key(to)), "no edge {from} → {to} found");
    }
    let cycles = cycles(&graph);
    assert!(cycles.is_empty(), "the module import graph has cycles:\n{}", describe(&graph, &cycles));
}

#[test]
fn a_cycle_through_crate_and_super_paths_is_found_and_named() {
    let files = sources(&[
        ("lib.rs", "pub mod a;\npub mod b;\nmod c;\npub struct Root;\nuse a::A;"),
        ("a/mod.rs", "mod inner;\npub struct A;"),
        ("a/inner.rs", "use super::A;\nuse crate::{c::C, b};"),
        ("b.rs", "// crate::a::A in a comment\nfn f() -> &'static str { \"crate::a::A\" }\nuse crate::Root;"),
        ("c.rs", "pub struct C;\nfn g() { let _ = crate::b::f; }"),
    ]);
    let graph = graph(&files);
    let cycles = cycles(&graph);
    // The shortest way round: a → c → b → lib → a is one step longer.
    assert_eq!(cycles, vec![vec!["a".to_string(), "b".into(), "lib".into()]]);
    let text = describe(&graph, &cycles);
    assert!(text.contains("a → b → lib → a"), "{text}");
    assert!(text.contains("a/inner.rs:2"), "{text}");
    assert!(text.contains("lib.rs:5"), "{text}");
}

#[test]
fn super_in_an_inline_module_and_text_in_strings_make_no_edge() {
    let files = sources(&[
        ("lib.rs", "pub mod a;\npub mod b;"),
        ("a.rs", "use crate::b::B;\n#[cfg(test)]\nmod tests {\n    use super::*;\n}\nconst S: &str = r#\"super::x\"#;"),
        ("b.rs", "pub struct B;\nfn c() -> char { '{' }\nmod m { fn f() { let _ = super::B; } }\nfn l<'a>() {}"),
    ]);
    let graph = graph(&files);
    assert!(cycles(&graph).is_empty(), "{graph:?}");
    assert_eq!(graph["a"].keys().collect::<Vec<_>>(), ["b"]);
    assert!(!graph.contains_key("b"), "{graph:?}");
}

fn sources(files: &[(&str, &str)]) -> Vec<(String, String)> {
    files.iter().map(|(path, text)| (path.to_string(), text.to_string())).collect()
}

/// Every .rs file under `dir` as (path relative to src/, text), sorted.
fn collect_sources(root: &Path, dir: &Path, out: &mut Vec<(String, String)>) {
    let mut entries: Vec<_> = std::fs::read_dir(dir).unwrap().map(|e| e.unwrap().path()).collect();
    entries.sort();
    for path in entries {
        if path.is_dir() {
            collect_sources(root, &path, out);
        } else if path.extension().is_some_and(|e| e == "rs") {
            let relative = path.strip_prefix(root).unwrap().to_string_lossy().replace('\\', "/");
            out.push((relative, std::fs::read_to_string(&path).unwrap()));
        }
    }
}

/// The graph between top-level modules (see the module comment).
fn graph(files: &[(String, String)]) -> Graph {
    assert!(files.iter().any(|(path, _)| path == "lib.rs"), "no lib.rs");
    let modules = top_level_modules(files);
    let mut graph = Graph::new();
    for (path, text) in files.iter().filter(|(path, _)| path != "main.rs") {
        let place = module_path(path);
        let from = place.first().cloned().unwrap_or_else(|| "lib".into());
        for (to, line, written) in references(&place, &tokens(&blank(text)), &modules) {
            if to != from {
                let reference = Reference { file: path.clone(), line, path: written };
                graph.entry(from.clone()).or_default().entry(to).or_insert(reference);
            }
        }
    }
    graph
}

/// The module a file is: `solve/bounce.rs` → [solve, bounce], `solve/mod.rs` → [solve], lib.rs → [].
fn module_path(file: &str) -> Vec<String> {
    let mut parts: Vec<String> = file.trim_end_matches(".rs").split('/').map(str::to_string).collect();
    if matches!(parts.last().map(String::as_str), Some("mod" | "lib")) {
        parts.pop();
    }
    parts
}

/// The top-level modules: every file and folder directly under src/ but
/// lib.rs and main.rs (lib.rs declares some of them through a macro, so its
/// `mod` lines are not read).
fn top_level_modules(files: &[(String, String)]) -> BTreeSet<String> {
    let name = |path: &str| path.split('/').next().unwrap_or(path).trim_end_matches(".rs").to_string();
    files.iter().map(|(path, _)| name(path)).filter(|m| m != "lib" && m != "main").collect()
}

/// (target node, line, path as written) for every cross-module path in one file's tokens.
fn references(
    place: &[String],
    tokens: &[(String, usize)],
    modules: &BTreeSet<String>,
) -> Vec<(String, usize, String)> {
    let is = |i: usize, text: &str| tokens.get(i).is_some_and(|t| t.0 == text);
    let node = |name: &str| if modules.contains(name) { name.to_string() } else { "lib".to_string() };
    let mut found = Vec::new();
    // Open braces, each with the inline module it opens (if any): `super::` is relative to them.
    let mut braces: Vec<Option<String>> = Vec::new();
    for i in 0..tokens.len() {
        let (token, line) = (&tokens[i].0, tokens[i].1);
        match token.as_str() {
            "{" => braces.push((i >= 2 && is(i - 2, "mod")).then(|| tokens[i - 1].0.clone())),
            "}" => {
                braces.pop();
            }
            _ => {}
        }
        let after_path = i > 0 && (is(i - 1, "::") || is(i - 1, "$") || is(i - 1, "."));
        if after_path || !is(i + 1, "::") {
            continue;
        }
        let root_file = place.is_empty() && braces.iter().all(Option::is_none);
        let mut here: Vec<String> = place.iter().cloned().chain(braces.iter().flatten().cloned()).collect();
        let mut next = i;
        let start_from_root = match token.as_str() {
            "crate" => true,
            "super" => {
                while is(next, "super") && is(next + 1, "::") {
                    here.pop();
                    next += 2;
                }
                next -= 2;
                here.is_empty()
            }
            "self" if root_file => true,
            name if root_file && modules.contains(name) => {
                found.push((name.to_string(), line, written(tokens, i)));
                continue;
            }
            _ => continue,
        };
        let targets = if start_from_root { first_segments(tokens, next + 2) } else { vec![here[0].clone()] };
        found.extend(targets.iter().map(|t| (node(t), line, written(tokens, i))));
    }
    found
}

/// The first segment of each path a `crate::` (or `super::`) prefix leads to:
/// `x` for `crate::x::y`, `a` and `c` for `crate::{a::b, c}`.
fn first_segments(tokens: &[(String, usize)], at: usize) -> Vec<String> {
    let Some((first, _)) = tokens.get(at) else { return Vec::new() };
    if first != "{" {
        return vec![first.clone()];
    }
    let (mut depth, mut segments, mut expect) = (0, Vec::new(), true);
    for (token, _) in &tokens[at..] {
        match token.as_str() {
            "{" => depth += 1,
            "}" if depth == 1 => break,
            "}" => depth -= 1,
            "," if depth == 1 => expect = true,
            name if depth == 1 && expect => {
                // `self` in a group is the prefix itself: the crate root.
                segments.push(if name == "self" { "lib".to_string() } else { name.to_string() });
                expect = false;
            }
            _ => {}
        }
    }
    segments
}

/// The path as written from token `at` on, for the failure message.
fn written(tokens: &[(String, usize)], at: usize) -> String {
    let (mut text, mut depth) = (String::new(), 0);
    for (token, _) in &tokens[at..] {
        if text.len() > 60 {
            text.push('…');
            break;
        }
        match token.as_str() {
            "{" if text.ends_with("::") => depth += 1,
            "}" if depth > 0 => depth -= 1,
            "," if depth > 0 => {}
            ";" | "(" | ")" | "=" | "<" | ">" | "," | "{" | "}" => break,
            _ => {}
        }
        text.push_str(token);
        if token == "," {
            text.push(' ');
        }
    }
    text
}

/// Identifiers, `::` and single punctuation characters, each with its line (1-based).
fn tokens(text: &str) -> Vec<(String, usize)> {
    let chars: Vec<char> = text.chars().collect();
    let (mut out, mut line, mut i) = (Vec::new(), 1, 0);
    while i < chars.len() {
        let c = chars[i];
        if c == '\n' {
            line += 1;
            i += 1;
        } else if c.is_whitespace() {
            i += 1;
        } else if c.is_alphanumeric() || c == '_' {
            let start = i;
            while i < chars.len() && (chars[i].is_alphanumeric() || chars[i] == '_') {
                i += 1;
            }
            out.push((chars[start..i].iter().collect(), line));
        } else if c == ':' && chars.get(i + 1) == Some(&':') {
            out.push(("::".to_string(), line));
            i += 2;
        } else {
            out.push((c.to_string(), line));
            i += 1;
        }
    }
    out
}

/// `text` with comments, string literals and character literals replaced by
/// spaces, newlines kept (so lines still count): a path in a doc comment or an
/// error message is no dependency, and a `{` in a string must not open a block.
fn blank(text: &str) -> String {
    let chars: Vec<char> = text.chars().collect();
    let mut out = String::with_capacity(text.len());
    let mut i = 0;
    let skip = |out: &mut String, from: usize, to: usize| {
        out.extend(chars[from..to.min(chars.len())].iter().map(|&c| if c == '\n' { '\n' } else { ' ' }));
        to.min(chars.len())
    };
    while i < chars.len() {
        let at = |k: usize| chars.get(i + k).copied().unwrap_or('\0');
        let word_before = i > 0 && (chars[i - 1].is_alphanumeric() || chars[i - 1] == '_');
        if at(0) == '/' && at(1) == '/' {
            let end = (i..chars.len()).find(|&k| chars[k] == '\n').unwrap_or(chars.len());
            i = skip(&mut out, i, end);
        } else if at(0) == '/' && at(1) == '*' {
            i = skip(&mut out, i, block_comment_end(&chars, i));
        } else if !word_before && let Some(end) = raw_string_end(&chars, i) {
            i = skip(&mut out, i, end);
        } else if at(0) == '"' || (at(0) == 'b' && at(1) == '"' && !word_before) {
            let mut k = i + if at(0) == 'b' { 2 } else { 1 };
            while k < chars.len() && chars[k] != '"' {
                k += if chars[k] == '\\' { 2 } else { 1 };
            }
            i = skip(&mut out, i, k + 1);
        } else if at(0) == '\'' && (at(1) == '\\' || (at(1) != '\'' && at(2) == '\'')) {
            // A character literal; `'a` alone is a lifetime or label and stays.
            // Its closing quote comes after the character, or after an escape's first two characters.
            let mut k = if at(1) == '\\' { i + 3 } else { i + 2 };
            while k < chars.len() && chars[k] != '\'' {
                k += if chars[k] == '\\' { 2 } else { 1 };
            }
            i = skip(&mut out, i, k + 1);
        } else {
            out.push(chars[i]);
            i += 1;
        }
    }
    out
}

/// Where the (nestable) block comment starting at `start` ends.
fn block_comment_end(chars: &[char], start: usize) -> usize {
    let (mut depth, mut k) = (0, start);
    while k + 1 < chars.len() {
        match (chars[k], chars[k + 1]) {
            ('/', '*') => (depth, k) = (depth + 1, k + 2),
            ('*', '/') => {
                (depth, k) = (depth - 1, k + 2);
                if depth == 0 {
                    return k;
                }
            }
            _ => k += 1,
        }
    }
    chars.len()
}

/// Where a raw string (`r"…"`, `r#"…"#`, `br#"…"#`) starting at `start` ends, if one does.
fn raw_string_end(chars: &[char], start: usize) -> Option<usize> {
    let mut k = start + usize::from(chars.get(start) == Some(&'b'));
    if chars.get(k) != Some(&'r') {
        return None;
    }
    k += 1;
    let hashes = chars[k..].iter().take_while(|&&c| c == '#').count();
    k += hashes;
    if chars.get(k) != Some(&'"') {
        return None;
    }
    let close: Vec<char> = std::iter::once('"').chain(std::iter::repeat_n('#', hashes)).collect();
    (k + 1..chars.len()).find(|&e| chars[e..].starts_with(&close)).map(|e| e + close.len())
}

/// One shortest cycle through each group of mutually reachable nodes
/// (Tarjan's strongly connected components), starting at its first node by name.
fn cycles(graph: &Graph) -> Vec<Vec<String>> {
    let components = strongly_connected(graph);
    let mut found = Vec::new();
    for component in components.into_iter().filter(|c| c.len() > 1) {
        let start = component.iter().min().unwrap().clone();
        // Breadth-first from `start` back to it, inside the component.
        let mut came_from: BTreeMap<String, String> = BTreeMap::new();
        let mut queue = VecDeque::from([start.clone()]);
        'search: while let Some(node) = queue.pop_front() {
            for next in graph.get(&node).into_iter().flat_map(|e| e.keys()).filter(|n| component.contains(*n)) {
                if *next == start {
                    came_from.insert(start.clone(), node.clone());
                    break 'search;
                }
                if !came_from.contains_key(next) {
                    came_from.insert(next.clone(), node.clone());
                    queue.push_back(next.clone());
                }
            }
        }
        let mut cycle = vec![came_from[&start].clone()];
        while *cycle.last().unwrap() != start {
            cycle.push(came_from[cycle.last().unwrap()].clone());
        }
        cycle.reverse();
        found.push(cycle);
    }
    found
}

fn strongly_connected(graph: &Graph) -> Vec<BTreeSet<String>> {
    struct State<'g> {
        graph: &'g Graph,
        index: BTreeMap<&'g str, usize>,
        low: BTreeMap<&'g str, usize>,
        stack: Vec<&'g str>,
        components: Vec<BTreeSet<String>>,
    }
    fn visit<'g>(s: &mut State<'g>, node: &'g str) {
        let n = s.index.len();
        s.index.insert(node, n);
        s.low.insert(node, n);
        s.stack.push(node);
        for next in s.graph.get(node).into_iter().flat_map(|e| e.keys()) {
            if !s.index.contains_key(next.as_str()) {
                visit(s, next);
                let low = s.low[node].min(s.low[next.as_str()]);
                s.low.insert(node, low);
            } else if s.stack.contains(&next.as_str()) {
                let low = s.low[node].min(s.index[next.as_str()]);
                s.low.insert(node, low);
            }
        }
        if s.low[node] == s.index[node] {
            let mut component = BTreeSet::new();
            while let Some(top) = s.stack.pop() {
                component.insert(top.to_string());
                if top == node {
                    break;
                }
            }
            s.components.push(component);
        }
    }
    let mut state =
        State { graph, index: BTreeMap::new(), low: BTreeMap::new(), stack: Vec::new(), components: Vec::new() };
    for node in graph.keys() {
        if !state.index.contains_key(node.as_str()) {
            visit(&mut state, node);
        }
    }
    state.components
}

/// Each cycle as `a → b → a` with the reference behind each step, then every
/// other edge between the modules it ties together (all of them must be
/// looked at to untie it).
fn describe(graph: &Graph, cycles: &[Vec<String>]) -> String {
    let mut text = String::new();
    let edge = |from: &str, to: &str| {
        let r = &graph[from][to];
        format!("    {from} → {to}: src/{}:{} {}\n", r.file, r.line, r.path)
    };
    for cycle in cycles {
        let steps: BTreeSet<(&str, &str)> =
            (0..cycle.len()).map(|k| (cycle[k].as_str(), cycle[(k + 1) % cycle.len()].as_str())).collect();
        text.push_str(&format!("  {} → {}\n", cycle.join(" → "), cycle[0]));
        text.extend(steps.iter().map(|(from, to)| edge(from, to)));
        let component: BTreeSet<String> =
            strongly_connected(graph).into_iter().find(|c| c.contains(&cycle[0])).unwrap();
        if component.len() > cycle.len() {
            let members: Vec<&str> = component.iter().map(String::as_str).collect();
            text.push_str(&format!("  in one knot with it ({}), also:\n", members.join(", ")));
            for from in &component {
                for to in graph[from].keys().filter(|to| component.contains(*to)) {
                    if !steps.contains(&(from.as_str(), to.as_str())) {
                        text.push_str(&edge(from, to));
                    }
                }
            }
        }
    }
    text
}
