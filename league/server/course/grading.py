"""Grades: an assignment's rubric applied to its students' finals, and the files gradebooks import.

Nothing here touches the database: the caller gives one `Entry` a student (and one a baseline)
with their final's figures on the private tracks, and `grade(entries, rubric, late_penalty=)`
returns the rows, best first. The rules, in one place:

- **Rank** among students only, by the board's order (completed fraction, then mean return); equal
  figures share a rank (1, 1, 3). Baselines are reference lines: their figures where they would
  stand, no rank, no grade. A revoked student is flagged and ranked among the active students as
  if they were the only one added (they move no one else): `rank` and `students` are theirs alone.
- **Points**: the rubric's, within [0, max_points], times the assignment's late penalty factor if
  the final was late. A student **without a final** (no submission by their close time that
  passed validation) gets 0 points; one whose close time has not passed, whose final is not
  decided yet (an upload of theirs still to be validated or evaluated on the public tracks:
  `deciding`), or whose final has **no private result of the current settings** (not evaluated
  yet, its evaluation failed, or only of other settings: `stale`) gets an empty grade, so that a
  gradebook never reads a pending grade as a zero. Each row's `status` says which: graded, no
  final, open, pending, stale, or reference (a baseline). A row's `note` says when its private
  result changed after the assignment was published (re-evaluated, or graded after it).
- **Rubrics** (`Rubric`, JSON the instructor sets): points by completed fraction (steps or
  linear) plus points by rank (linear or a table), or a formula over `completed` (fraction 0-1),
  `mean_speed`, `rank` and `students` (the count ranked), with numbers, + - * / **, min(),
  max(), clip(x, low, high), comparisons, `and`/`or` and `a if condition else b`. The formula is
  parsed with `ast` and evaluated by walking an allow-list of nodes: nothing of Python runs.

Exports (`league.spreadsheet.csv_text` cells): `generic_csv` (every column, baselines as
reference lines), `canvas_csv` and `moodle_csv` (the gradebooks' import formats; one column an
assignment) and `course_csv` (one column an assignment and the total). The server README's
"Grades" section says how to import each.
"""
from __future__ import annotations

import ast
import functools
import math
import operator
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Annotated, Any, Literal

from pydantic import BaseModel, ConfigDict, Field, field_validator, model_validator
from pydantic_core import PydanticCustomError

from league.spreadsheet import csv_text

VARIABLES = ("completed", "mean_speed", "rank", "students")
MAX_FORMULA_CHARS = 500
MAX_FORMULA_DEPTH = 25
MAX_FORMULA_NODES = 200
MAX_EXPONENT = 100  # |a number written as an exponent|: 2 ** 1000 is a typo, not a rubric
MAX_POINTS = 10_000
DECIMALS = 2  # points are rounded to hundredths, in the API and the files alike


class FormulaError(ValueError):
    """A formula that cannot be read, or cannot be evaluated for some figures (the message says why)."""


# --------------------------------------------------------------------------- formulas

BINARY: dict[type, Callable[[float, float], float]] = {
    ast.Add: operator.add, ast.Sub: operator.sub, ast.Mult: operator.mul, ast.Div: operator.truediv,
    ast.Pow: math.pow,  # never complex, and OverflowError rather than a huge integer
}
UNARY: dict[type, Callable[[float], float]] = {ast.USub: operator.neg, ast.UAdd: operator.pos}
COMPARE: dict[type, Callable[[float, float], bool]] = {
    ast.Lt: operator.lt, ast.LtE: operator.le, ast.Gt: operator.gt, ast.GtE: operator.ge, ast.Eq: operator.eq,
    ast.NotEq: operator.ne,
}
FUNCTIONS: dict[str, tuple[Callable[..., float], int, int | None]] = {  # name: (function, least, most arguments)
    "min": (min, 2, None), "max": (max, 2, None), "clip": (lambda x, low, high: min(max(x, low), high), 3, 3),
}
ALLOWED = "numbers, " + ", ".join(VARIABLES) + ", + - * / **, min(), max(), clip(), comparisons, and/or, " \
          "and `a if condition else b`"


def parse_formula(text: str) -> ast.expr:
    """The formula's tree, checked: only allowed nodes and names, within the size bounds."""
    if len(text) > MAX_FORMULA_CHARS:
        raise FormulaError(f"the formula is {len(text)} characters long, more than {MAX_FORMULA_CHARS}")
    try:
        tree = ast.parse(text.strip(), mode="eval").body
    except SyntaxError as error:
        where = f" (column {error.offset})" if error.offset else ""
        raise FormulaError(f"the formula is not an expression: {error.msg}{where}") from None
    except (ValueError, RecursionError, MemoryError):
        raise FormulaError("the formula is not an expression") from None
    if sum(1 for _ in ast.walk(tree)) > MAX_FORMULA_NODES:
        raise FormulaError(f"the formula has more than {MAX_FORMULA_NODES} parts")
    _check(tree, depth=1)
    return tree


def _check(node: ast.AST, depth: int) -> None:
    if depth > MAX_FORMULA_DEPTH:
        raise FormulaError(f"the formula is nested deeper than {MAX_FORMULA_DEPTH} levels")
    if isinstance(node, ast.Constant):
        if type(node.value) not in (int, float):
            raise FormulaError(f"the formula may use only numbers, not {node.value!r}")
    elif isinstance(node, ast.Name):
        if node.id not in VARIABLES:
            raise FormulaError(f"unknown name {node.id!r}: the formula may use {', '.join(VARIABLES)}")
    elif isinstance(node, ast.Call):
        _check_call(node)
    elif isinstance(node, ast.BinOp) and type(node.op) in BINARY:
        if isinstance(node.op, ast.Pow) and _exponent_too_big(node.right):
            raise FormulaError(f"an exponent is larger than {MAX_EXPONENT}")
    elif not (isinstance(node, (ast.IfExp, ast.BoolOp)) or (isinstance(node, ast.UnaryOp) and type(node.op) in UNARY)
              or (isinstance(node, ast.Compare) and all(type(op) in COMPARE for op in node.ops))):
        raise FormulaError(f"the formula may not use {_shown(node)}: it may use {ALLOWED}")
    children = node.args if isinstance(node, ast.Call) else ast.iter_child_nodes(node)
    for child in children:
        if not isinstance(child, (ast.operator, ast.unaryop, ast.cmpop, ast.boolop, ast.expr_context)):
            _check(child, depth + 1)


def _check_call(node: ast.Call) -> None:
    if not isinstance(node.func, ast.Name) or node.func.id not in FUNCTIONS:
        raise FormulaError(f"the formula may call only {', '.join(f + '()' for f in FUNCTIONS)}")
    name, (_, least, most) = node.func.id, FUNCTIONS[node.func.id]
    if node.keywords or any(isinstance(arg, ast.Starred) for arg in node.args):
        raise FormulaError(f"{name}() takes plain arguments")
    if len(node.args) < least or (most is not None and len(node.args) > most):
        wanted = "3 arguments (value, low, high)" if name == "clip" else f"at least {least} arguments"
        raise FormulaError(f"{name}() takes {wanted}, not {len(node.args)}")


def _exponent_too_big(node: ast.expr) -> bool:
    if isinstance(node, ast.UnaryOp) and type(node.op) in UNARY:
        node = node.operand
    return isinstance(node, ast.Constant) and abs(node.value) > MAX_EXPONENT


def _shown(node: ast.AST) -> str:
    """A node's kind as a student of the formula knows it."""
    op = getattr(node, "op", None)
    if isinstance(node, ast.BinOp) or isinstance(node, ast.UnaryOp):
        return {ast.FloorDiv: "//", ast.Mod: "%", ast.MatMult: "@", ast.BitAnd: "&", ast.BitOr: "|", ast.BitXor: "^",
                ast.LShift: "<<", ast.RShift: ">>", ast.Invert: "~", ast.Not: "not"}.get(type(op), "that operator")
    if isinstance(node, ast.Compare):
        return "`in` or `is`"
    return {ast.Attribute: "attributes (a.b)", ast.Subscript: "indexing (a[b])", ast.Lambda: "lambda",
            ast.NamedExpr: ":=", ast.JoinedStr: "strings"}.get(type(node), type(node).__name__)


def evaluate_formula(tree: ast.expr, values: dict[str, float]) -> float:
    """The formula's value for these figures (floats throughout; comparisons give 1 or 0)."""
    try:
        result = _value(tree, values)
    except ZeroDivisionError:
        raise FormulaError(f"the formula divides by zero when {_figures(values)}") from None
    except OverflowError:
        raise FormulaError(f"the formula overflows when {_figures(values)}") from None
    except ValueError:  # math.pow of a negative number to a fraction, or of zero to a negative power
        raise FormulaError(f"the formula has no real value when {_figures(values)}") from None
    return result


def _value(node: ast.expr, values: dict[str, float]) -> float:
    if isinstance(node, ast.Constant):
        return float(node.value)
    if isinstance(node, ast.Name):
        return float(values[node.id])
    if isinstance(node, ast.BinOp):
        return _finite(BINARY[type(node.op)](_value(node.left, values), _value(node.right, values)))
    if isinstance(node, ast.UnaryOp):
        return UNARY[type(node.op)](_value(node.operand, values))
    if isinstance(node, ast.Call):
        return FUNCTIONS[node.func.id][0](*(_value(arg, values) for arg in node.args))
    if isinstance(node, ast.IfExp):
        return _value(node.body if _value(node.test, values) else node.orelse, values)
    if isinstance(node, ast.BoolOp):  # Python's: the first false (and) or true (or) operand, else the last
        for operand in node.values:
            result = _value(operand, values)
            if bool(result) != isinstance(node.op, ast.And):
                return result
        return result
    left = _value(node.left, values)  # ast.Compare, chained as Python chains it
    for op, right_node in zip(node.ops, node.comparators):
        right = _value(right_node, values)
        if not COMPARE[type(op)](left, right):
            return 0.0
        left = right
    return 1.0


def _finite(x: float) -> float:
    if not math.isfinite(x):
        raise OverflowError
    return x


def _figures(values: dict[str, float]) -> str:
    return ", ".join(f"{name}={values[name]:g}" for name in VARIABLES)


# figures a formula must have a value for when it is set: the edges (nothing completed, a car
# that never moved, a single student, the last of many) as well as the middle
PROBES = [{"completed": c, "mean_speed": s, "rank": r, "students": n} for c in (0.0, 0.5, 1.0) for s in (0.0, 0.5, 3.0)
          for r, n in ((1, 1), (1, 2), (2, 2), (1, 30), (15, 30), (30, 30))]


# --------------------------------------------------------------------------- rubrics


def _invalid(message: str) -> PydanticCustomError:
    """A rubric's problem as the API says it (pydantic would prefix a ValueError with "Value error, ")."""
    return PydanticCustomError("invalid_rubric", message)


class Step(BaseModel):
    model_config = ConfigDict(extra="forbid")

    completed: float = Field(ge=0, le=1, description="the completed fraction (0-1) that earns these points")
    points: float = Field(ge=0, le=MAX_POINTS)


class CompletedSteps(BaseModel):
    """Points of the highest step the completed fraction reaches (none reached: 0)."""

    model_config = ConfigDict(extra="forbid")

    kind: Literal["steps"]
    steps: list[Step] = Field(min_length=1, max_length=20)

    @field_validator("steps")
    @classmethod
    def _rising(cls, steps: list[Step]) -> list[Step]:
        for low, high in zip(steps, steps[1:]):
            if high.completed <= low.completed:
                raise _invalid("steps must be in order of rising completed fractions, each once")
            if high.points < low.points:
                raise _invalid("a step of a higher completed fraction may not give fewer points")
        return steps

    @property
    def most(self) -> float:
        return self.steps[-1].points

    def points_for(self, completed: float) -> float:
        return max((step.points for step in self.steps if completed >= step.completed), default=0.0)


class CompletedLinear(BaseModel):
    """0 points up to `zero_at`, all `points` from `full_at`, in proportion between."""

    model_config = ConfigDict(extra="forbid")

    kind: Literal["linear"]
    points: float = Field(ge=0, le=MAX_POINTS)
    zero_at: float = Field(0.0, ge=0, le=1)
    full_at: float = Field(1.0, ge=0, le=1)

    @model_validator(mode="after")
    def _ordered(self) -> CompletedLinear:
        if self.full_at <= self.zero_at:
            raise _invalid("full_at must be above zero_at")
        return self

    @property
    def most(self) -> float:
        return self.points

    def points_for(self, completed: float) -> float:
        return self.points * min(max((completed - self.zero_at) / (self.full_at - self.zero_at), 0.0), 1.0)


class RankLinear(BaseModel):
    """All `points` for the best student, 0 for the last, evenly between; a single student earns all."""

    model_config = ConfigDict(extra="forbid")

    kind: Literal["linear"]
    points: float = Field(ge=0, le=MAX_POINTS)

    @property
    def most(self) -> float:
        return self.points

    def points_for(self, rank: int, students: int) -> float:
        return self.points if students <= 1 else self.points * max(students - rank, 0) / (students - 1)


class RankTable(BaseModel):
    """`points[0]` for rank 1, `points[1]` for rank 2, ...; 0 below the table."""

    model_config = ConfigDict(extra="forbid")

    kind: Literal["table"]
    points: list[Annotated[float, Field(ge=0, le=MAX_POINTS)]] = Field(min_length=1, max_length=100)

    @field_validator("points")
    @classmethod
    def _falling(cls, points: list[float]) -> list[float]:
        if any(lower > higher for higher, lower in zip(points, points[1:])):
            raise _invalid("a lower rank may not give more points than a higher one")
        return points

    @property
    def most(self) -> float:
        return self.points[0]

    def points_for(self, rank: int, students: int) -> float:
        return self.points[rank - 1] if rank <= len(self.points) else 0.0


class PointsRubric(BaseModel):
    """Points by completed fraction plus points by rank among students (either may be left out)."""

    model_config = ConfigDict(extra="forbid")

    kind: Literal["points"]
    max_points: float = Field(gt=0, le=MAX_POINTS)
    completed: Annotated[CompletedSteps | CompletedLinear, Field(discriminator="kind")] | None = None
    rank: Annotated[RankLinear | RankTable, Field(discriminator="kind")] | None = None

    @model_validator(mode="after")
    def _parts(self) -> PointsRubric:
        if self.completed is None and self.rank is None:
            raise _invalid("give points by completed fraction, by rank, or both")
        most = sum(part.most for part in (self.completed, self.rank) if part is not None)
        if most > self.max_points + 1e-9:
            raise _invalid(f"the parts give up to {most:g} points, more than max_points ({self.max_points:g})")
        return self

    def raw_points(self, figures: dict[str, float]) -> float:
        total = 0.0
        if self.completed is not None:
            total += self.completed.points_for(figures["completed"])
        if self.rank is not None:
            total += self.rank.points_for(int(figures["rank"]), int(figures["students"]))
        return total


class FormulaRubric(BaseModel):
    """A formula's value (kept within [0, max_points])."""

    model_config = ConfigDict(extra="forbid")

    kind: Literal["formula"]
    max_points: float = Field(gt=0, le=MAX_POINTS)
    formula: str = Field(min_length=1, max_length=MAX_FORMULA_CHARS,
                         description=f"an expression over {', '.join(VARIABLES)}; it may use {ALLOWED}")

    @field_validator("formula")
    @classmethod
    def _readable(cls, formula: str) -> str:
        try:
            tree = parse_formula(formula)
            for figures in PROBES:
                evaluate_formula(tree, figures)
        except FormulaError as error:
            raise _invalid(str(error)) from None
        return formula

    def raw_points(self, figures: dict[str, float]) -> float:
        return evaluate_formula(_parsed(self.formula), figures)


@functools.lru_cache(maxsize=64)
def _parsed(formula: str) -> ast.expr:
    """Parsed once, not once a student (the tree is only read)."""
    return parse_formula(formula)


Rubric = Annotated[PointsRubric | FormulaRubric, Field(discriminator="kind")]


class RubricModel(BaseModel):
    """A wrapper that reads a rubric from stored JSON: `RubricModel(rubric=data).rubric`."""

    rubric: Rubric


def read_rubric(data: dict[str, Any]) -> PointsRubric | FormulaRubric:
    """A rubric from its JSON (pydantic.ValidationError with every problem otherwise)."""
    return RubricModel(rubric=data).rubric


# --------------------------------------------------------------------------- grading


@dataclass(frozen=True)
class Entry:
    """A line to grade: a student (or a baseline, `baseline=True`) and their final's figures on the
    private tracks. `closed` False: their close time has not passed (no final yet); `submission_id`
    None: no final; `completed` None: the final has no private result of the current settings
    (`stale`: it has one of other settings only)."""

    name: str
    user_id: int | None = None
    email: str | None = None
    student_id: str | None = None
    canvas_id: str | None = None  # Canvas's own ids, from its gradebook export (league.server.course.roster)
    sis_login_id: str | None = None
    baseline: bool = False
    revoked: bool = False
    submission_id: int | None = None
    completed: float | None = None  # the fraction of the private episodes completed, 0-1
    mean_return: float | None = None
    mean_speed: float | None = None
    late: bool = False
    closed: bool = True
    stale: bool = False
    deciding: bool = False  # closed, the final not decided yet (league.server.course.assignments)
    note: str | None = None  # how its private result changed since the publication (None: it did not)

    @property
    def evaluated(self) -> bool:
        return self.closed and self.submission_id is not None and self.completed is not None

    def score(self) -> tuple[float, float]:
        """The board's order: completed fraction, then mean return."""
        return (self.completed, self.mean_return if self.mean_return is not None else -math.inf)


@dataclass(frozen=True)
class GradeRow:
    entry: Entry
    rank: int | None  # among students; None for baselines and for students without a private result
    students: int | None  # how many were ranked with them
    penalty: float | None  # the factor the points were multiplied by (1 on time); None when not graded
    points: float | None

    @property
    def status(self) -> str:
        e = self.entry
        if e.baseline:
            return "reference"
        if not e.closed:
            return "open"
        if e.deciding:
            return "pending"
        if e.submission_id is None:
            return "no final"
        if not e.evaluated:
            return "stale" if e.stale else "pending"
        return "graded"

    def as_dict(self) -> dict[str, Any]:
        e = self.entry
        return {"name": e.name, "status": self.status, "role": "baseline" if e.baseline else "student",
                "email": e.email, "student_id": e.student_id, "submission_id": e.submission_id,
                "completed": e.completed, "mean_return": e.mean_return, "mean_speed": e.mean_speed, "rank": self.rank,
                "students": self.students, "late": e.late, "penalty": self.penalty, "points": self.points,
                "revoked": e.revoked, "revised": e.note is not None, "note": e.note}


def grade(entries: Sequence[Entry], rubric: PointsRubric | FormulaRubric, *,
          late_penalty: float | None = None) -> list[GradeRow]:
    """Every entry's row: those with a private result best first (baselines among them as reference
    lines), then students not graded yet (open, pending, stale), then students without a final, by name.
    `late_penalty`: the factor a late final's points are multiplied by (None: late costs nothing).
    Raises FormulaError if the rubric's formula has no value for some student's figures."""
    ranked = [e for e in entries if e.evaluated and not e.baseline and not e.revoked]
    scores = sorted((e.score() for e in ranked), reverse=True)
    rows = []
    for entry in entries:
        rank = students = None
        if entry.evaluated and not entry.baseline:
            better = sum(1 for score in scores if score > entry.score())
            rank, students = better + 1, len(scores) + (1 if entry.revoked else 0)
        rows.append(_row(entry, rank, students, rubric, late_penalty))
    return sorted(rows, key=_order)


def _row(entry: Entry, rank: int | None, students: int | None, rubric, late_penalty: float | None) -> GradeRow:
    if entry.baseline or not entry.closed or entry.deciding or (
            entry.submission_id is not None and not entry.evaluated):
        return GradeRow(entry, rank, students, None, None)
    if entry.submission_id is None:
        return GradeRow(entry, None, None, None, 0.0)
    figures = {"completed": entry.completed, "mean_speed": entry.mean_speed or 0.0, "rank": rank,
               "students": students}
    penalty = late_penalty if entry.late and late_penalty is not None else 1.0
    points = min(max(rubric.raw_points(figures), 0.0), rubric.max_points) * penalty
    return GradeRow(entry, rank, students, penalty, round(points, DECIMALS))


def _order(row: GradeRow) -> tuple:
    e = row.entry
    if e.evaluated:
        return (0, tuple(-x for x in e.score()), e.baseline, e.name)
    return (2 if e.closed and not e.deciding and e.submission_id is None else 1, (), False, e.name)


def student_rows(rows: Sequence[GradeRow]) -> list[GradeRow]:
    return [row for row in rows if not row.entry.baseline]


# --------------------------------------------------------------------------- exports

GENERIC_COLUMNS = ["name", "status", "role", "email", "student_id", "submission", "completed", "mean_return",
                   "mean_speed", "rank", "students", "late", "penalty", "points", "revoked", "note"]
CANVAS_STUDENT_COLUMNS = ["Student", "ID", "SIS User ID", "SIS Login ID", "Section"]
CANVAS_POINTS_POSSIBLE = "Points Possible"  # the row Canvas reads each column's maximum from
MOODLE_IDENTIFIERS = {"email": "Email address", "idnumber": "ID number"}  # Moodle's names for the user fields


@dataclass(frozen=True)
class Graded:
    """An assignment's name, maximum and rows: what a gradebook column is made of."""

    name: str
    max_points: float
    rows: Sequence[GradeRow]


def _yes(flag: bool) -> str | None:
    return "yes" if flag else None


def generic_csv(rows: Sequence[GradeRow]) -> str:
    """Every row and column: students and the baselines' reference lines (role), figures rounded."""
    return csv_text(GENERIC_COLUMNS, [[
        e.name, row.status, "baseline" if e.baseline else "student", e.email, e.student_id, e.submission_id,
        _round(e.completed, 4), _round(e.mean_return, 3), _round(e.mean_speed, 3), row.rank, row.students,
        _yes(e.late), row.penalty, row.points, _yes(e.revoked), e.note] for row in rows for e in [row.entry]])


def _round(x: float | None, decimals: int) -> float | None:
    return None if x is None else round(x, decimals)


def _students(graded: Sequence[Graded]) -> list[Entry]:
    """Each student once (by user id, else name), by name: the union of the assignments' rows."""
    seen: dict[Any, Entry] = {}
    for assignment in graded:
        for row in student_rows(assignment.rows):
            seen.setdefault(row.entry.user_id or row.entry.name, row.entry)
    return sorted(seen.values(), key=lambda e: (e.name.casefold(), e.name))


def _points_by_student(graded: Sequence[Graded]) -> list[dict[Any, float | None]]:
    return [{row.entry.user_id or row.entry.name: row.points for row in student_rows(a.rows)} for a in graded]


def course_csv(graded: Sequence[Graded]) -> str:
    """A Points Possible line (each assignment's maximum, as Canvas has it), then one line a
    student: identity, revoked, each assignment's points, the total (empty while any of theirs is)."""
    names = [a.name for a in graded]
    points = _points_by_student(graded)
    lines: list[list] = [[CANVAS_POINTS_POSSIBLE, None, None, None, *(a.max_points for a in graded),
                          round(sum(a.max_points for a in graded), DECIMALS)]]
    for e in _students(graded):
        mine = [column.get(e.user_id or e.name) for column in points]
        total = None if any(p is None for p in mine) else round(sum(mine), DECIMALS)
        lines.append([e.name, e.email, e.student_id, _yes(e.revoked), *mine, total])
    return csv_text(["name", "email", "student_id", "revoked", *names, "total"], lines)


def canvas_csv(graded: Sequence[Graded]) -> str:
    """Canvas's gradebook import: the five student columns, a column of points an assignment headed
    by its name (Canvas matches an assignment of that title, or creates one), and the Points
    Possible row. Canvas finds each student by ID (the Canvas user ID), then SIS User ID (our
    student id), then SIS Login ID (Canvas's, else our email), then by name or "Last, First" name
    (canvas-lms GradebookImporter#process_student): the ids come from a roster imported from
    Canvas's own export, and the names are written as Canvas exports them."""
    points = _points_by_student(graded)
    lines: list[list] = [[CANVAS_POINTS_POSSIBLE, None, None, None, None, *(a.max_points for a in graded)]]
    for e in _students(graded):
        lines.append([sortable_name(e.name), e.canvas_id, e.student_id, e.sis_login_id or e.email, None,
                      *(column.get(e.user_id or e.name) for column in points)])
    return csv_text(CANVAS_STUDENT_COLUMNS + [a.name for a in graded], lines)


def sortable_name(name: str) -> str:
    """A name as Canvas exports it ("Last, First"): the last word is taken for the surname, which
    Canvas needs only for a student it finds by no id (a name written so already is kept)."""
    first, space, last = name.rpartition(" ")
    return f"{last}, {first}" if space and "," not in name else name


@dataclass(frozen=True)
class CanvasMatch:
    """How Canvas will find the students of a grade file: `by_id`, their Canvas ID, SIS User ID or a
    SIS Login ID of Canvas's own; `by_email`, only an email written as SIS Login ID (found where the
    institution's logins are its addresses); `by_name`, nothing but the name."""

    students: int
    by_id: list[str]
    by_email: list[str]
    by_name: list[str]

    def summary(self) -> str:
        parts = [f"{len(self.by_id)} of {self.students} rows carry an id Canvas matches (ID, SIS User ID or "
                 "SIS Login ID)"]
        if self.by_email:
            parts.append(f"{len(self.by_email)} only an email as SIS Login ID, matched only where Canvas logins "
                         f"are email addresses: {', '.join(self.by_email)}")
        if self.by_name:
            parts.append(f"{len(self.by_name)} only a name, matched only if Canvas spells it the same: "
                         f"{', '.join(self.by_name)}")
        return "; ".join(parts)


def canvas_match(graded: Sequence[Graded]) -> CanvasMatch:
    """How Canvas will find each student of `canvas_csv(graded)`."""
    students = _students(graded)
    found: dict[str, list[str]] = {"id": [], "email": [], "name": []}
    for e in students:
        found["id" if e.canvas_id or e.student_id or e.sis_login_id else "email" if e.email else "name"].append(e.name)
    return CanvasMatch(len(students), found["id"], found["email"], found["name"])


def moodle_csv(graded: Sequence[Graded], *,
               identifier: Literal["email", "idnumber"] = "email") -> tuple[str, list[str]]:
    """Moodle's CSV grade import: the identifier column (mapped in Moodle to the user's email or ID
    number) and a column of points an assignment. Students without that identifier are left out,
    their names returned: Moodle gives a line with an empty identifier the grade of the line above."""
    points = _points_by_student(graded)
    lines, left_out = [], []
    for e in _students(graded):
        key = e.email if identifier == "email" else e.student_id
        if not key:
            left_out.append(e.name)
            continue
        lines.append([key, *(column.get(e.user_id or e.name) for column in points)])
    return csv_text([MOODLE_IDENTIFIERS[identifier]] + [a.name for a in graded], lines), left_out
