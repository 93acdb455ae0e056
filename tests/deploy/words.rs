//! Command lines out of the deploy files, split into words the way their runner splits
//! them, with variables replaced by sample values: shell (Slurm batch script), systemd
//! `ExecStart=`, HTCondor `arguments`. An undefined variable is an error, not a guess.

use std::collections::HashMap;

/// Sample values of variables; a name absent here is unset.
pub type Vars = HashMap<String, String>;

/// Builds [`Vars`] from pairs.
pub fn vars(pairs: &[(&str, &str)]) -> Vars {
    pairs.iter().map(|(k, v)| (k.to_string(), v.to_string())).collect()
}

/// A word or a shell control operator (`;`, `&`, `|`, `&&`, `||`).
#[derive(Debug, PartialEq)]
enum Token {
    Word(String),
    Operator,
}

/// Logical lines of a shell script or unit file: `\`-newline joined, with the number of
/// the line each starts on.
pub fn logical_lines(text: &str) -> Vec<(usize, String)> {
    let mut out = Vec::new();
    let mut current: Option<(usize, String)> = None;
    for (i, line) in text.lines().enumerate() {
        let (start, mut acc) = current.take().unwrap_or((i + 1, String::new()));
        match line.strip_suffix('\\') {
            Some(head) => {
                acc.push_str(head);
                acc.push(' ');
                current = Some((start, acc));
            }
            None => {
                acc.push_str(line);
                out.push((start, acc));
            }
        }
    }
    out.extend(current);
    out
}

/// Every `gridlight ...` command in a shell script: the words from the one naming the
/// binary (`gridlight`, `/path/gridlight`, or a variable that expands to one) up to the
/// next control operator. Comment lines are skipped.
pub fn shell_commands(text: &str, vars: &Vars) -> Result<Vec<(usize, Vec<String>)>, String> {
    let mut commands = Vec::new();
    for (line_no, line) in logical_lines(text) {
        if line.trim_start().starts_with('#') {
            continue;
        }
        let tokens = split_shell(&line, vars).map_err(|e| format!("line {line_no}: {e}"))?;
        let mut words = None::<Vec<String>>;
        for token in tokens {
            match (token, words.as_mut()) {
                (Token::Word(w), Some(acc)) => acc.push(w),
                (Token::Word(w), None) if is_gridlight(&w) => words = Some(vec![w]),
                (Token::Operator, Some(_)) => commands.extend(words.take().map(|w| (line_no, w))),
                _ => {}
            }
        }
        commands.extend(words.map(|w| (line_no, w)));
    }
    Ok(commands)
}

/// Whether `word` names the gridlight binary.
pub fn is_gridlight(word: &str) -> bool {
    std::path::Path::new(word).file_name().is_some_and(|n| n == "gridlight")
}

/// Splits one line as a POSIX shell would (quotes, backslashes, `$VAR`, `${VAR}`,
/// `${VAR:-default}`, `${VAR:?message}`, `#` comments), without globbing.
fn split_shell(line: &str, vars: &Vars) -> Result<Vec<Token>, String> {
    let chars: Vec<char> = line.chars().collect();
    let mut tokens = Vec::new();
    let mut word: Option<String> = None;
    let mut i = 0;
    while i < chars.len() {
        let c = chars[i];
        match c {
            ' ' | '\t' => {
                tokens.extend(word.take().map(Token::Word));
                i += 1;
            }
            '#' if word.is_none() => break,
            ';' | '&' | '|' => {
                tokens.extend(word.take().map(Token::Word));
                tokens.push(Token::Operator);
                i += if chars.get(i + 1) == Some(&c) { 2 } else { 1 };
            }
            '\\' => {
                let next = chars.get(i + 1).ok_or("trailing backslash")?;
                word.get_or_insert_with(String::new).push(*next);
                i += 2;
            }
            '\'' => {
                let end = find(&chars, i + 1, '\'').ok_or("unterminated single quote")?;
                word.get_or_insert_with(String::new).extend(&chars[i + 1..end]);
                i = end + 1;
            }
            '"' => {
                let w = word.get_or_insert_with(String::new);
                i += 1;
                loop {
                    match chars.get(i) {
                        None => return Err("unterminated double quote".into()),
                        Some('"') => break,
                        Some('\\') if matches!(chars.get(i + 1), Some('"' | '\\' | '$')) => {
                            w.push(chars[i + 1]);
                            i += 2;
                        }
                        Some('$') => i = expand(&chars, i, vars, w)?,
                        Some(&other) => {
                            w.push(other);
                            i += 1;
                        }
                    }
                }
                i += 1;
            }
            '$' => i = expand(&chars, i, vars, word.get_or_insert_with(String::new))?,
            _ => {
                word.get_or_insert_with(String::new).push(c);
                i += 1;
            }
        }
    }
    tokens.extend(word.map(Token::Word));
    Ok(tokens)
}

fn find(chars: &[char], from: usize, c: char) -> Option<usize> {
    chars[from..].iter().position(|&x| x == c).map(|p| from + p)
}

/// Expands the parameter at `chars[at] == '$'` into `out`; returns the index after it.
fn expand(chars: &[char], at: usize, vars: &Vars, out: &mut String) -> Result<usize, String> {
    let lookup = |name: &str| vars.get(name).cloned();
    if chars.get(at + 1) == Some(&'{') {
        let end = matching_brace(chars, at + 2).ok_or("unterminated ${")?;
        let inner: String = chars[at + 2..end].iter().collect();
        let (name, op, rest) = match inner.find(":-").or_else(|| inner.find(":?")) {
            Some(p) => (&inner[..p], &inner[p..p + 2], &inner[p + 2..]),
            None => (inner.as_str(), "", ""),
        };
        match (lookup(name), op) {
            (Some(v), _) => out.push_str(&v),
            (None, ":-") => {
                let words = split_shell(rest, vars)?;
                for t in words {
                    if let Token::Word(w) = t {
                        out.push_str(&w);
                    }
                }
            }
            (None, _) => return Err(format!("variable `{name}` has no sample value")),
        }
        return Ok(end + 1);
    }
    // `$1` is one digit; a name runs on over letters, digits and underscores.
    let len = match chars.get(at + 1) {
        Some(c) if c.is_ascii_digit() => 1,
        _ => chars[at + 1..].iter().take_while(|c| c.is_ascii_alphanumeric() || **c == '_').count(),
    };
    if len == 0 {
        out.push('$');
        return Ok(at + 1);
    }
    let name: String = chars[at + 1..at + 1 + len].iter().collect();
    out.push_str(&lookup(&name).ok_or(format!("variable `{name}` has no sample value"))?);
    Ok(at + 1 + len)
}

fn matching_brace(chars: &[char], from: usize) -> Option<usize> {
    let mut depth = 1;
    for (i, &c) in chars.iter().enumerate().skip(from) {
        match c {
            '{' => depth += 1,
            '}' => {
                depth -= 1;
                if depth == 0 {
                    return Some(i);
                }
            }
            _ => {}
        }
    }
    None
}

/// The words of a systemd `ExecStart=` value: `%H` as a host name, `${VAR}`/`$VAR` from
/// `vars`, quotes as systemd reads them (the same as the shell's for these files), the
/// exec prefixes (`-`, `@`, `:`, `+`, `!`) removed.
pub fn systemd_exec(value: &str, vars: &Vars) -> Result<Vec<String>, String> {
    let value = value.trim_start_matches(['-', '@', ':', '+', '!']).replace("%H", "desk-17");
    let tokens = split_shell(&value, vars)?;
    tokens
        .into_iter()
        .map(|t| match t {
            Token::Word(w) => Ok(w),
            Token::Operator => Err("systemd runs no shell: `;`, `&` or `|` in ExecStart".into()),
        })
        .collect()
}

/// HTCondor's `$(name)` macros in `text`, expanded from `macros` (case-insensitively, as
/// HTCondor does), recursively.
pub fn condor_expand(text: &str, macros: &Vars) -> Result<String, String> {
    expand_macros(text, macros, 0)
}

fn expand_macros(text: &str, macros: &Vars, depth: u32) -> Result<String, String> {
    if depth > 32 {
        return Err("macros expand into each other forever".into());
    }
    let mut out = String::new();
    let mut rest = text;
    while let Some(start) = rest.find("$(") {
        out.push_str(&rest[..start]);
        let end = rest[start..].find(')').ok_or("unterminated $(")? + start;
        let name = &rest[start + 2..end];
        let value = macros
            .iter()
            .find(|(k, _)| k.eq_ignore_ascii_case(name))
            .map(|(_, v)| v.clone())
            .ok_or(format!("macro `{name}` is not defined"))?;
        out.push_str(&expand_macros(&value, macros, depth + 1)?);
        rest = &rest[end + 1..];
    }
    out.push_str(rest);
    Ok(out)
}

/// HTCondor's "new syntax" `arguments = "..."`: in double quotes, split on spaces, single
/// quotes group, a doubled quote is a literal one.
pub fn condor_arguments(value: &str) -> Result<Vec<String>, String> {
    let inner = value
        .trim()
        .strip_prefix('"')
        .and_then(|v| v.strip_suffix('"'))
        .ok_or("arguments must be in double quotes (HTCondor's new syntax)")?;
    let chars: Vec<char> = inner.chars().collect();
    let mut words = Vec::new();
    let mut word: Option<String> = None;
    let mut quoted = false;
    let mut i = 0;
    while i < chars.len() {
        match (chars[i], quoted) {
            ('\'', _) if chars.get(i + 1) == Some(&'\'') => {
                word.get_or_insert_with(String::new).push('\'');
                i += 1;
            }
            ('\'', _) => {
                quoted = !quoted;
                word.get_or_insert_with(String::new);
            }
            ('"', _) if chars.get(i + 1) == Some(&'"') => {
                word.get_or_insert_with(String::new).push('"');
                i += 1;
            }
            ('"', _) => return Err("a lone double quote inside arguments".into()),
            (' ' | '\t', false) => words.extend(word.take()),
            (c, _) => word.get_or_insert_with(String::new).push(c),
        }
        i += 1;
    }
    if quoted {
        return Err("unterminated single quote in arguments".into());
    }
    words.extend(word);
    Ok(words)
}

#[cfg(test)]
mod tests {
    // Exercised through the deploy tests; the splitter's own cases are here.
    use super::*;

    #[test]
    fn shell_words_expand_and_stop_at_operators() {
        let v = vars(&[("A", "x y"), ("1", "h:1")]);
        let cmds = shell_commands(
            "exec \"${G:-gridlight}\" worker --master \"$1\" --n '$A' ${B:-$A} && echo\n",
            &v,
        )
        .unwrap();
        assert_eq!(cmds.len(), 1);
        assert_eq!(
            cmds[0].1,
            ["gridlight", "worker", "--master", "h:1", "--n", "$A", "x y"].map(String::from)
        );
        assert!(shell_commands("gridlight worker $UNSET\n", &v).is_err());
    }

    #[test]
    fn condor_arguments_split_as_htcondor_does() {
        assert_eq!(condor_arguments("\"a 'b c' d''e\"").unwrap(), ["a", "b c", "d'e"]);
        assert!(condor_arguments("a b").is_err());
    }
}
