//! Strict tokenizer for one line of G-code: words (`letter number`), comments, `%` lines.
//!
//! Hand-written rather than built on the `gcode` crate (0.7.0): that crate stores values
//! as `f32`, panics on `G429496730` (u32 overflow in `Number::from_str` in debug builds),
//! lets a `(` comment run across lines (silently swallowing the commands on them), and
//! reports `#1` or `[1+2]` only as generic "unexpected token" diagnostics. The subset the
//! gantry accepts is small enough that a strict scanner is shorter than the glue around
//! the crate, and it names exactly what is unsupported.

use super::MAX_WORD_MAGNITUDE;

/// One word of a block, e.g. `X-12.5`.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Word {
    /// Upper-case address letter.
    pub letter: char,
    /// Numeric value as written (program units; not yet converted).
    pub value: f64,
    /// The word as written (letter upper-cased, whitespace removed), for messages.
    pub text: String,
}

/// Why a line could not be tokenized.
#[derive(Debug, Clone, PartialEq, Eq)]
pub(crate) enum LexError {
    /// `<what>` is not supported (the caller appends " is not supported").
    Unsupported(String),
    /// Malformed text: the full message.
    Syntax(String),
}

/// Letters the interpreter understands (G, M, value words). Anything else is unsupported.
const SUPPORTED_LETTERS: &str = "FGHIJKLMNPQRSTXYZ";

/// Longest expression text quoted in a message.
const MAX_QUOTED_CHARS: usize = 40;

/// Tokenizes one line (without its `\n`). Whitespace between tokens, and between a
/// letter and its number, is skipped (as in RS274NGC); it is not allowed inside a number.
pub(crate) fn lex_line(line: &str) -> Result<Vec<Word>, LexError> {
    let chars: Vec<char> = line.chars().collect();
    let mut words = Vec::new();
    let mut i = 0usize;
    // True until the first token of the line has been seen (for `/` and `%`).
    let mut at_start = true;
    let mut percent_line = false;
    while let Some(&c) = chars.get(i) {
        if is_blank(c) {
            i += 1;
            continue;
        }
        let first = at_start;
        at_start = false;
        match c {
            '(' => i = skip_paren_comment(&chars, i)?,
            ';' => break,
            '%' if first => {
                percent_line = true;
                i += 1;
            }
            '%' => {
                return Err(LexError::Syntax(
                    "'%' must stand alone at the start of its line".into(),
                ))
            }
            _ if percent_line => {
                return Err(LexError::Syntax(
                    "only comments may follow '%' on its line".into(),
                ))
            }
            '/' if first => return Err(LexError::Unsupported("block delete (/)".into())),
            '#' => return Err(LexError::Unsupported(parameter_text(&chars, i))),
            '[' | ']' => return Err(LexError::Unsupported(expression_text(&chars, i))),
            _ if c.is_ascii_alphabetic() => {
                let (word, next) = scan_word(&chars, i)?;
                words.push(word);
                i = next;
            }
            _ if c.is_ascii_digit() || matches!(c, '.' | '+' | '-') => {
                let end = run_end(&chars, i, |c| {
                    c.is_ascii_digit() || matches!(c, '.' | '+' | '-')
                });
                let text: String = chars.get(i..end).unwrap_or_default().iter().collect();
                return Err(LexError::Syntax(format!(
                    "number {text} has no letter before it"
                )));
            }
            _ => return Err(LexError::Syntax(format!("unexpected character {c:?}"))),
        }
    }
    Ok(words)
}

fn is_blank(c: char) -> bool {
    matches!(c, ' ' | '\t' | '\r' | '\x0c')
}

/// Index one past the end of the run of `pred` characters starting at `i`.
fn run_end(chars: &[char], i: usize, pred: impl Fn(char) -> bool) -> usize {
    let mut j = i;
    while chars.get(j).is_some_and(|&c| pred(c)) {
        j += 1;
    }
    j
}

/// Skips a `( … )` comment starting at `i`; returns the index after `)`.
/// Comments must close on their own line and do not nest (RS274NGC).
fn skip_paren_comment(chars: &[char], i: usize) -> Result<usize, LexError> {
    let mut j = i + 1;
    while let Some(&c) = chars.get(j) {
        match c {
            ')' => return Ok(j + 1),
            '(' => {
                return Err(LexError::Syntax(
                    "'(' inside a comment: comments do not nest".into(),
                ))
            }
            _ => j += 1,
        }
    }
    Err(LexError::Syntax(
        "comment is not closed: missing ')'".into(),
    ))
}

/// "parameter #1" / "parameter #<name>" for the message.
fn parameter_text(chars: &[char], i: usize) -> String {
    let end = if chars.get(i + 1) == Some(&'<') {
        chars
            .iter()
            .skip(i)
            .position(|&c| c == '>')
            .map_or(chars.len(), |p| i + p + 1)
    } else {
        run_end(chars, i + 1, |c| c.is_ascii_digit())
    };
    format!("parameter {}", quoted(chars, i, end))
}

/// "expression [1+2]" for the message (up to the matching `]`).
fn expression_text(chars: &[char], i: usize) -> String {
    let mut depth = 0i32;
    let mut end = chars.len();
    for (j, &c) in chars.iter().enumerate().skip(i) {
        match c {
            '[' => depth += 1,
            ']' => {
                depth -= 1;
                if depth <= 0 {
                    end = j + 1;
                    break;
                }
            }
            _ => {}
        }
    }
    format!("expression {}", quoted(chars, i, end))
}

fn quoted(chars: &[char], start: usize, end: usize) -> String {
    let slice = chars.get(start..end.min(chars.len())).unwrap_or_default();
    let mut s: String = slice.iter().take(MAX_QUOTED_CHARS).collect();
    if slice.len() > MAX_QUOTED_CHARS {
        s.push('…');
    }
    s
}

/// What to call a letter the gantry does not support.
fn unsupported_letter(letter: char) -> String {
    let what = match letter {
        'O' => return "O-word (program number or subroutine)".into(),
        'A' | 'B' | 'C' => "rotary axis",
        'U' | 'V' | 'W' => "secondary linear axis",
        'D' => "cutter compensation register",
        'E' => "extruder axis of 3D printers",
        _ => return format!("{letter} word"),
    };
    format!("{letter} word ({what})")
}

/// Scans `letter [blank] [sign] [blank] digits[.digits]` starting at the letter.
fn scan_word(chars: &[char], i: usize) -> Result<(Word, usize), LexError> {
    let letter = chars.get(i).copied().unwrap_or('?').to_ascii_uppercase();
    if !SUPPORTED_LETTERS.contains(letter) {
        return Err(LexError::Unsupported(unsupported_letter(letter)));
    }
    let mut j = run_end(chars, i + 1, is_blank);
    let mut number = String::new();
    if let Some(&s) = chars.get(j).filter(|&&c| c == '+' || c == '-') {
        number.push(s);
        j = run_end(chars, j + 1, is_blank);
    }
    let end = run_end(chars, j, |c| c.is_ascii_digit() || c == '.');
    number.extend(chars.get(j..end).unwrap_or_default());
    let digits = chars.get(j..end).unwrap_or_default();
    if digits.is_empty() {
        return Err(match chars.get(end) {
            Some('#') => LexError::Unsupported(parameter_text(chars, end)),
            Some('[') => LexError::Unsupported(expression_text(chars, end)),
            _ => LexError::Syntax(format!("{letter}{number} has no number after the letter")),
        });
    }
    let dots = digits.iter().filter(|&&c| c == '.').count();
    if dots > 1 || digits.iter().all(|&c| c == '.') {
        return Err(LexError::Syntax(format!("bad number {letter}{number}")));
    }
    let value: f64 = number
        .parse()
        .map_err(|_| LexError::Syntax(format!("bad number {letter}{number}")))?;
    if !(value.abs() <= MAX_WORD_MAGNITUDE) {
        return Err(LexError::Syntax(format!(
            "{letter}{number} is out of range (magnitude at most {MAX_WORD_MAGNITUDE:e})"
        )));
    }
    let text = format!("{letter}{number}");
    Ok((
        Word {
            letter,
            value,
            text,
        },
        end,
    ))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn texts(line: &str) -> Vec<String> {
        lex_line(line)
            .unwrap()
            .into_iter()
            .map(|w| w.text)
            .collect()
    }

    #[test]
    fn words_comments_and_blanks() {
        assert_eq!(
            texts("g1 x-1.5 Y+.25 (move) z 3. ;tail"),
            ["G1", "X-1.5", "Y+.25", "Z3."]
        );
        let w = lex_line("X - 2").unwrap();
        assert_eq!(w[0].value, -2.0);
        assert_eq!(texts("% (start)"), Vec::<String>::new());
        assert_eq!(texts("(a) (b)G0"), ["G0"]);
    }

    #[test]
    fn rejects() {
        let e = |s: &str| lex_line(s).unwrap_err();
        assert_eq!(e("G1 X#1"), LexError::Unsupported("parameter #1".into()));
        assert_eq!(e("#<r>=2"), LexError::Unsupported("parameter #<r>".into()));
        assert_eq!(
            e("G1 X[1+[2]] Y1"),
            LexError::Unsupported("expression [1+[2]]".into())
        );
        assert_eq!(
            e("/G0 X1"),
            LexError::Unsupported("block delete (/)".into())
        );
        assert_eq!(
            e("O100 sub"),
            LexError::Unsupported("O-word (program number or subroutine)".into())
        );
        assert_eq!(e("G1 X1.2.3"), LexError::Syntax("bad number X1.2.3".into()));
        assert_eq!(e("G1 X."), LexError::Syntax("bad number X.".into()));
        assert_eq!(
            e("G1 X-"),
            LexError::Syntax("X- has no number after the letter".into())
        );
        assert_eq!(
            e("G1 10"),
            LexError::Syntax("number 10 has no letter before it".into())
        );
        assert_eq!(
            e("G1 X1 $"),
            LexError::Syntax("unexpected character '$'".into())
        );
        assert_eq!(
            e("(a (b))"),
            LexError::Syntax("'(' inside a comment: comments do not nest".into())
        );
        assert_eq!(
            e("(open"),
            LexError::Syntax("comment is not closed: missing ')'".into())
        );
        assert_eq!(
            e("G0 %"),
            LexError::Syntax("'%' must stand alone at the start of its line".into())
        );
        assert_eq!(
            e("X20000000"),
            LexError::Syntax("X20000000 is out of range (magnitude at most 1e7)".into())
        );
    }
}
