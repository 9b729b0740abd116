//! The commands README.md and the user guide (docs/guide/*.md) show: every `pathwave ...` line of their ```sh blocks
//! must parse, so that a renamed flag or a stricter value parser fails here, not in a reader's shell.
use std::path::{Path, PathBuf};
use std::process::Command;

fn root() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR"))
}

/// README.md, then every page of the guide: a page added later is checked without being listed here.
fn pages() -> Vec<PathBuf> {
    let mut guide: Vec<PathBuf> = std::fs::read_dir(root().join("docs/guide"))
        .expect("docs/guide/ can be listed")
        .map(|entry| entry.expect("docs/guide/ can be listed").path())
        .filter(|path| path.extension().is_some_and(|e| e == "md"))
        .collect();
    guide.sort();
    [vec![root().join("README.md")], guide].concat()
}

/// The lines of the page's ```sh blocks (other blocks hold YAML, synopses or diagrams), with the number of each
/// one's first line: a trailing backslash continues a command on the next line, as in the shell.
fn sh_lines(page: &str) -> Vec<(usize, String)> {
    let mut lines = Vec::new();
    // Inside a fence: whether it is a ```sh one. Fences may be indented under a list item.
    let mut block: Option<bool> = None;
    let mut pending: Option<(usize, String)> = None;
    for (i, line) in page.lines().enumerate() {
        let line = line.trim();
        if line.starts_with("```") {
            block = match block {
                Some(_) => None,
                None => Some(line == "```sh"),
            };
            continue;
        }
        if block != Some(true) {
            continue;
        }
        let (first, joined) = match pending.take() {
            Some((first, before)) => (first, format!("{before} {line}")),
            None => (i + 1, line.to_string()),
        };
        match joined.strip_suffix('\\') {
            Some(head) => pending = Some((first, head.trim_end().to_string())),
            None => lines.push((first, joined)),
        }
    }
    lines
}

/// The command without what the shell adds around pathwave's arguments: a comment, a pipe, a redirection or a
/// second command.
fn cut(line: &str) -> &str {
    let mut quote = None;
    let mut end = line.len();
    for (i, c) in line.char_indices() {
        match quote {
            Some(q) if c == q => quote = None,
            Some(_) => {}
            None if c == '\'' || c == '"' => quote = Some(c),
            // A # starts a comment only at the start of a word: `-o out/frame.####.exr` is an argument.
            None if c == '#' && (i == 0 || line[..i].ends_with(' ')) => {
                end = i;
                break;
            }
            None => {}
        }
    }
    let mut line = &line[..end];
    for separator in [" | ", " > ", " 2>", " && ", " ;"] {
        if let Some(at) = line.find(separator) {
            line = &line[..at];
        }
    }
    line.trim()
}

/// Words as the shell splits them, for the quoting the guide uses: single and double quotes, no escapes. A quoted
/// `$(...)` stays one word, unexpanded, which is all the parser needs.
fn words(line: &str) -> Vec<String> {
    let mut words = Vec::new();
    let mut word: Option<String> = None;
    let mut quote = None;
    for c in line.chars() {
        match quote {
            Some(q) if c == q => quote = None,
            Some(_) => word.get_or_insert_with(String::new).push(c),
            None if c == '\'' || c == '"' => {
                quote = Some(c);
                word = Some(word.take().unwrap_or_default());
            }
            None if c.is_whitespace() => words.extend(word.take()),
            None => word.get_or_insert_with(String::new).push(c),
        }
    }
    words.extend(word);
    words
}

/// `NAME=value`, as in `VK_DRIVER_FILES=... pathwave render ...`: the environment of the command, not an argument.
fn is_assignment(word: &str) -> bool {
    word.split_once('=').is_some_and(|(name, _)| {
        name.starts_with(|c: char| c == '_' || c.is_ascii_alphabetic())
            && name.chars().all(|c| c == '_' || c.is_ascii_alphanumeric())
    })
}

#[test]
fn every_command_the_guide_shows_parses() {
    let mut checked = 0;
    let mut failures = Vec::new();
    for page in pages() {
        let text = std::fs::read_to_string(&page).unwrap_or_else(|e| panic!("{}: {e}", page.display()));
        let name = page.strip_prefix(root()).unwrap_or(&page).display().to_string();
        for (line, command) in sh_lines(&text) {
            let argv = words(cut(&command));
            let mut args = argv.iter().skip_while(|w| is_assignment(w));
            if args.next().map(String::as_str) != Some("pathwave") {
                continue;
            }
            // PATHWAVE_PARSE_ONLY: the binary parses its arguments with clap and exits, so that no command here
            // renders, opens a window or needs its files; a bad flag or value exits 2 with clap's message.
            let out = Command::new(env!("CARGO_BIN_EXE_pathwave"))
                .args(args)
                .env("PATHWAVE_PARSE_ONLY", "1")
                .output()
                .expect("the pathwave binary runs");
            checked += 1;
            // The project's own files a command names must exist: parsing alone would not notice a renamed scene.
            let argv: Vec<&String> = argv.iter().skip_while(|w| is_assignment(w)).collect();
            for word in argv.iter().filter(|w| w.starts_with("scenes/") || w.starts_with("ci/")) {
                if !root().join(word.as_str()).exists() {
                    failures.push(format!("{name}:{line}: {command}\n{word} does not exist"));
                }
            }
            if !out.status.success() {
                let stderr = String::from_utf8_lossy(&out.stderr);
                failures.push(format!("{name}:{line}: {command}\n{stderr}"));
            }
        }
    }
    assert!(
        failures.is_empty(),
        "commands in the guide that pathwave refuses:\n\n{}",
        failures.join("\n")
    );
    // The pages show 43; far fewer means the extraction broke, and a test that finds nothing passes nothing.
    assert!(
        checked >= 40,
        "found only {checked} pathwave commands in README.md and docs/guide/"
    );
}
