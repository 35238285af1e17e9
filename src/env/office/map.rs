//! The Office map file: a grid world's walls, letters (propositions) and start cell as text.
//!
//! ```text
//! # '#' starts a comment line (outside the picture).
//! legend:                  <- the letters, one per line, in bit order: `letter = description`
//! A = corner A
//! c = coffee
//! * = plant
//! map:                     <- the picture, to the end of the file (blank lines may follow it)
//! +-----+-----+
//! |. A .|. . c|            <- a cell row: cells at odd columns, walls between them
//! |     |     |
//! |. . @   * .|            <- '@' start, '.' empty cell, a legend letter
//! +-----+-----+            <- a wall row: '-' under/over a cell is a wall, ' ' open
//! ```
//!
//! The picture is `2·rows + 1` lines of `2·columns + 1` characters (trailing whitespace is
//! ignored). Line `2i + 1` (0-based, from the top) holds the cells of row `y = rows − 1 − i`:
//! cell `x` at character `2x + 1`, and between cells `x` and `x + 1` (character `2x + 2`) a
//! `'|'` (wall) or `' '` (open). The lines in between hold, under each cell, a `'-'` (wall)
//! or `' '` (open); their remaining characters (corners) are any of `+ - | ' '` and mean
//! nothing. The outer border is wall all round. A move towards a wall, or off the grid,
//! leaves the agent where it is.
//!
//! Each cell is `.` (empty), `@` (the start: exactly one, unlabelled) or one letter of the
//! legend: the step that lands on it makes that proposition true. Every legend letter is on
//! the map at least once. A letter is any printable ASCII character that reward-machine
//! formulas do not reserve, other than the picture's own `. @ + - |`.
//!
//! Errors name the file, the 1-based line and column and what was expected. **Limits**
//! (checked while reading, before anything is allocated from them): at most [`MAX_ROWS`] rows,
//! [`MAX_COLUMNS`] columns, [`MAX_PROPS`] letters, [`MAX_LINE_CHARS`] characters per line and
//! [`MAX_DESCRIPTION_CHARS`] per description; [`read_map`] reads at most
//! [`crate::config_text::MAX_TEXT_FILE_BYTES`].

use crate::rm::labels::is_prop_char;
use crate::rm::{Vocabulary, MAX_PROPS};
use std::fmt;
use std::io;
use std::path::Path;

/// Most rows of a map.
pub const MAX_ROWS: usize = 64;
/// Most columns of a map.
pub const MAX_COLUMNS: usize = 64;
/// Longest line of a map file, in characters.
pub const MAX_LINE_CHARS: usize = 1_024;
/// Longest description of a letter, in characters.
pub const MAX_DESCRIPTION_CHARS: usize = 200;

/// Characters of the picture that cannot be letters.
const RESERVED: [char; 5] = ['.', '@', '+', '-', '|'];

/// Why a map file could not be read.
#[derive(Debug, thiserror::Error)]
pub enum MapError {
    #[error("{file}: cannot read: {error}")]
    Io { file: String, error: io::Error },
    /// The text is not a valid map; `line` and `column` are 1-based (`column` when one
    /// character is to blame, `line` when one line is).
    #[error("{}", Located { file, line: *line, column: *column, problem })]
    Syntax {
        file: String,
        line: Option<usize>,
        column: Option<usize>,
        problem: String,
    },
}

impl MapError {
    /// The 1-based line the error is about, when there is one.
    pub fn line(&self) -> Option<usize> {
        match self {
            MapError::Syntax { line, .. } => *line,
            MapError::Io { .. } => None,
        }
    }

    /// The 1-based column the error is about, when there is one.
    pub fn column(&self) -> Option<usize> {
        match self {
            MapError::Syntax { column, .. } => *column,
            MapError::Io { .. } => None,
        }
    }
}

/// `file:line:column: problem`, with the parts that are known.
struct Located<'a> {
    file: &'a str,
    line: Option<usize>,
    column: Option<usize>,
    problem: &'a str,
}

impl fmt::Display for Located<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}", self.file)?;
        if let Some(line) = self.line {
            write!(f, ":{line}")?;
            if let Some(column) = self.column {
                write!(f, ":{column}")?;
            }
        }
        write!(f, ": {}", self.problem)
    }
}

/// A grid world read from a map file. Cells are indexed `y * width + x`, `y = 0` the bottom
/// row.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct OfficeMap {
    width: usize,
    height: usize,
    vocab: Vocabulary,
    /// Description of each letter, in vocabulary order.
    descriptions: Vec<String>,
    /// The letter on each cell, if any.
    letters: Vec<Option<char>>,
    start: (usize, usize),
    /// `open_right[c]`: a move right from cell `c` is not blocked (false on the last column).
    open_right: Vec<bool>,
    /// `open_up[c]`: a move up from cell `c` is not blocked (false on the top row).
    open_up: Vec<bool>,
}

impl OfficeMap {
    pub fn width(&self) -> usize {
        self.width
    }

    pub fn height(&self) -> usize {
        self.height
    }

    /// The letters, in bit order.
    pub fn vocab(&self) -> &Vocabulary {
        &self.vocab
    }

    /// The legend's description of each letter, in bit order.
    pub fn descriptions(&self) -> &[String] {
        &self.descriptions
    }

    /// The letter on cell `(x, y)`, if any.
    pub fn letter(&self, x: usize, y: usize) -> Option<char> {
        self.letters[y * self.width + x]
    }

    /// The start cell `(x, y)`.
    pub fn start(&self) -> (usize, usize) {
        self.start
    }

    /// No wall between `(x, y)` and `(x + 1, y)`.
    pub fn open_right(&self, x: usize, y: usize) -> bool {
        self.open_right[y * self.width + x]
    }

    /// No wall between `(x, y)` and `(x, y + 1)`.
    pub fn open_up(&self, x: usize, y: usize) -> bool {
        self.open_up[y * self.width + x]
    }
}

/// Reads and parses a map file (at most [`crate::config_text::MAX_TEXT_FILE_BYTES`]).
pub fn read_map(path: &Path) -> Result<OfficeMap, MapError> {
    let file = path.display().to_string();
    let text = crate::config_text::read_text_file(path).map_err(|error| MapError::Io {
        file: file.clone(),
        error,
    })?;
    parse_map(&text, &file)
}

/// Parses the text of a map file; `source` names it in error messages.
pub fn parse_map(text: &str, source: &str) -> Result<OfficeMap, MapError> {
    let at = |line: usize, column: Option<usize>, problem: String| MapError::Syntax {
        file: source.to_string(),
        line: Some(line),
        column,
        problem,
    };

    #[derive(PartialEq)]
    enum Section {
        Header,
        Legend,
        Picture,
    }
    let mut section = Section::Header;
    let mut letters: Vec<char> = Vec::new();
    let mut descriptions: Vec<String> = Vec::new();
    let mut legend_lines: Vec<usize> = Vec::new();
    let mut legend_seen = false;
    // The picture's lines (1-based line number, characters), then whether it has ended.
    let mut picture: Vec<(usize, Vec<char>)> = Vec::new();
    let mut picture_ended_at: Option<usize> = None;

    for (k, raw) in text.lines().enumerate() {
        let line_no = k + 1;
        if raw.chars().count() > MAX_LINE_CHARS {
            return Err(at(
                line_no,
                None,
                format!("the line is longer than the limit of {MAX_LINE_CHARS} characters"),
            ));
        }
        let trimmed = raw.trim();
        let blank = trimmed.is_empty() || trimmed.starts_with('#');
        if section == Section::Picture {
            if blank {
                if !picture.is_empty() && picture_ended_at.is_none() {
                    picture_ended_at = Some(line_no);
                }
                continue;
            }
            if let Some(end) = picture_ended_at {
                return Err(at(
                    line_no,
                    None,
                    format!(
                        "the picture ended at line {end} (a blank or comment line); nothing but blank and comment lines may follow it"
                    ),
                ));
            }
            if picture.len() == 2 * MAX_ROWS + 1 {
                return Err(at(
                    line_no,
                    None,
                    format!(
                        "the picture has more than {} lines: more than the limit of {MAX_ROWS} rows",
                        2 * MAX_ROWS + 1
                    ),
                ));
            }
            picture.push((line_no, raw.trim_end().chars().collect()));
            continue;
        }
        if blank {
            continue;
        }
        match trimmed {
            "legend:" if legend_seen => {
                return Err(at(line_no, None, "a second 'legend:' section".into()));
            }
            "legend:" => {
                legend_seen = true;
                section = Section::Legend;
            }
            "map:" if !legend_seen => {
                return Err(at(
                    line_no,
                    None,
                    "'map:' before 'legend:': the legend names the letters first".into(),
                ));
            }
            "map:" => section = Section::Picture,
            _ if section == Section::Legend => {
                let (letter, description) = parse_legend_line(trimmed).map_err(|problem| {
                    let column = raw.chars().take_while(|c| c.is_whitespace()).count() + 1;
                    at(line_no, Some(column), problem)
                })?;
                if let Some(i) = letters.iter().position(|&l| l == letter) {
                    return Err(at(
                        line_no,
                        None,
                        format!(
                            "letter '{letter}' is already in the legend (line {})",
                            legend_lines[i]
                        ),
                    ));
                }
                if letters.len() == MAX_PROPS {
                    return Err(at(
                        line_no,
                        None,
                        format!("more than the limit of {MAX_PROPS} letters"),
                    ));
                }
                letters.push(letter);
                descriptions.push(description);
                legend_lines.push(line_no);
            }
            _ => {
                return Err(at(
                    line_no,
                    None,
                    format!("expected 'legend:' (then the letters) and 'map:' (then the picture), found \"{trimmed}\""),
                ));
            }
        }
    }
    let file_error = |problem: String| MapError::Syntax {
        file: source.to_string(),
        line: None,
        column: None,
        problem,
    };
    if section != Section::Picture {
        return Err(file_error(
            "no 'map:' line (the picture of the grid follows it)".into(),
        ));
    }
    if letters.is_empty() {
        return Err(file_error("the legend names no letter".into()));
    }
    let vocab: String = letters.iter().collect();
    let vocab = Vocabulary::parse(&vocab).map_err(|e| file_error(e.to_string()))?;

    // Shape: 2·rows + 1 lines of 2·columns + 1 characters.
    let Some((first_line, first)) = picture.first() else {
        return Err(file_error("the picture after 'map:' is empty".into()));
    };
    let n_chars = first.len();
    if n_chars < 3 || n_chars % 2 == 0 {
        return Err(at(
            *first_line,
            None,
            format!(
                "a picture line has 2·columns + 1 characters (an odd number, at least 3), this one {n_chars}"
            ),
        ));
    }
    if n_chars > 2 * MAX_COLUMNS + 1 {
        return Err(at(
            *first_line,
            None,
            format!(
                "{n_chars} characters is more than {}: more than the limit of {MAX_COLUMNS} columns",
                2 * MAX_COLUMNS + 1
            ),
        ));
    }
    for (line_no, chars) in &picture {
        if chars.len() != n_chars {
            return Err(at(
                *line_no,
                Some(chars.len().min(n_chars) + 1),
                format!(
                    "this picture line has {} characters, the first one (line {first_line}) {n_chars}",
                    chars.len()
                ),
            ));
        }
    }
    let n_lines = picture.len();
    if n_lines < 3 || n_lines.is_multiple_of(2) {
        return Err(at(
            picture[n_lines - 1].0,
            None,
            format!(
                "the picture has {n_lines} lines; it has 2·rows + 1 (an odd number, at least 3), starting and ending with a wall line"
            ),
        ));
    }
    let width = (n_chars - 1) / 2;
    let height = (n_lines - 1) / 2;

    let mut cell_letters = vec![None; width * height];
    let mut open_right = vec![false; width * height];
    let mut open_up = vec![false; width * height];
    let mut start: Option<((usize, usize), usize, usize)> = None;
    for (i, (line_no, chars)) in picture.iter().enumerate() {
        let outer_row = i == 0 || i == n_lines - 1;
        for (j, &ch) in chars.iter().enumerate() {
            let column = Some(j + 1);
            let outer_column = j == 0 || j == n_chars - 1;
            let bad = |problem: String| at(*line_no, column, problem);
            match (i % 2, j % 2) {
                // A corner.
                (0, 0) => {
                    if !matches!(ch, '+' | '-' | '|' | ' ') {
                        return Err(bad(format!(
                            "'{ch}' at a corner: expected '+', '-', '|' or ' '"
                        )));
                    }
                }
                // The wall above the cell below it (if any).
                (0, _) => {
                    let wall = match ch {
                        '-' => true,
                        ' ' => false,
                        _ => {
                            return Err(bad(format!(
                                "'{ch}' between two rows: expected '-' (wall) or ' ' (open)"
                            )))
                        }
                    };
                    if outer_row && !wall {
                        return Err(bad("the outer border must be a wall ('-')".into()));
                    }
                    if !outer_row {
                        // Line i lies between cell rows y + 1 (above) and y (below).
                        let y = height - 1 - i / 2;
                        open_up[y * width + (j - 1) / 2] = !wall;
                    }
                }
                // The wall between two cells of a row.
                (_, 0) => {
                    let wall = match ch {
                        '|' => true,
                        ' ' => false,
                        _ => {
                            return Err(bad(format!(
                                "'{ch}' between two cells: expected '|' (wall) or ' ' (open)"
                            )))
                        }
                    };
                    if outer_column && !wall {
                        return Err(bad("the outer border must be a wall ('|')".into()));
                    }
                    if !outer_column {
                        let y = height - 1 - (i - 1) / 2;
                        open_right[y * width + j / 2 - 1] = !wall;
                    }
                }
                // A cell.
                _ => {
                    let (x, y) = ((j - 1) / 2, height - 1 - (i - 1) / 2);
                    match ch {
                        '.' => {}
                        '@' => {
                            if let Some((_, l, c)) = start {
                                return Err(bad(format!(
                                    "a second start cell '@' (the first is at line {l}, column {c})"
                                )));
                            }
                            start = Some(((x, y), *line_no, j + 1));
                        }
                        _ if letters.contains(&ch) => cell_letters[y * width + x] = Some(ch),
                        _ => {
                            return Err(bad(format!(
                                "'{ch}' is not a cell: expected '.' (empty), '@' (start) or a letter of the legend (\"{vocab}\")"
                            )))
                        }
                    }
                }
            }
        }
    }
    let Some((start, _, _)) = start else {
        return Err(file_error("no start cell ('@') on the map".into()));
    };
    for (k, &letter) in letters.iter().enumerate() {
        if !cell_letters.contains(&Some(letter)) {
            return Err(at(
                legend_lines[k],
                None,
                format!("letter '{letter}' is in the legend but on no cell of the map"),
            ));
        }
    }
    Ok(OfficeMap {
        width,
        height,
        vocab,
        descriptions,
        letters: cell_letters,
        start,
        open_right,
        open_up,
    })
}

/// `X = description` → the letter and its description.
fn parse_legend_line(line: &str) -> Result<(char, String), String> {
    let mut chars = line.chars();
    let letter = chars.next().unwrap_or(' ');
    let rest = chars.as_str().trim_start();
    let Some(description) = rest.strip_prefix('=') else {
        return Err(format!(
            "expected a legend line 'letter = description', found \"{line}\""
        ));
    };
    if RESERVED.contains(&letter) || !is_prop_char(letter) {
        return Err(format!(
            "'{letter}' cannot be a letter (not '.', '@', '+', '-', '|', whitespace or a character formulas reserve: & | ! ( ) # , ' \")"
        ));
    }
    let description = description.trim();
    if description.chars().count() > MAX_DESCRIPTION_CHARS {
        return Err(format!(
            "the description of '{letter}' is longer than the limit of {MAX_DESCRIPTION_CHARS} characters"
        ));
    }
    Ok((letter, description.to_string()))
}

/// Writes a map in the file format; [`parse_map`] reads it back to an equal map. Corners
/// are drawn from the walls that meet there (`+` where walls cross, `-`/`|` along one).
pub fn write_map(map: &OfficeMap) -> String {
    let (w, h) = (map.width, map.height);
    let mut out = String::new();
    out.push_str("legend:\n");
    for (letter, description) in map.vocab.props().iter().zip(&map.descriptions) {
        if description.is_empty() {
            out.push_str(&format!("{letter} =\n"));
        } else {
            out.push_str(&format!("{letter} = {description}\n"));
        }
    }
    out.push_str("map:\n");
    // Wall between (x, y) and (x, y + 1); y = −1 and y = h − 1 are the outer border.
    let wall_above =
        |x: usize, y: isize| y < 0 || y as usize >= h - 1 || !map.open_up(x, y as usize);
    // Wall between (x, y) and (x + 1, y); x = −1 and x = w − 1 are the outer border.
    let wall_right =
        |x: isize, y: usize| x < 0 || x as usize >= w - 1 || !map.open_right(x as usize, y);
    for i in 0..2 * h + 1 {
        let mut line = String::with_capacity(2 * w + 1);
        if i % 2 == 0 {
            // Between cell rows y (below) and y + 1 (above).
            let y = h as isize - 1 - (i / 2) as isize;
            for j in 0..2 * w + 1 {
                if j % 2 == 1 {
                    line.push(if wall_above((j - 1) / 2, y) { '-' } else { ' ' });
                    continue;
                }
                let x = j as isize / 2 - 1;
                let horizontal = (x >= 0 && wall_above(x as usize, y))
                    || ((x + 1) < w as isize && wall_above((x + 1) as usize, y));
                let vertical = (y + 1 < h as isize && wall_right(x, (y + 1) as usize))
                    || (y >= 0 && wall_right(x, y as usize));
                line.push(match (horizontal, vertical) {
                    (true, true) => '+',
                    (true, false) => '-',
                    (false, true) => '|',
                    (false, false) => ' ',
                });
            }
        } else {
            let y = h - 1 - (i - 1) / 2;
            for j in 0..2 * w + 1 {
                if j % 2 == 0 {
                    let x = j as isize / 2 - 1;
                    line.push(if wall_right(x, y) { '|' } else { ' ' });
                } else {
                    let x = (j - 1) / 2;
                    line.push(match map.letter(x, y) {
                        Some(letter) => letter,
                        None if (x, y) == map.start => '@',
                        None => '.',
                    });
                }
            }
        }
        out.push_str(&line);
        out.push('\n');
    }
    out
}
