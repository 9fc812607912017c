"""league.server.course.grading: rubrics, formulas, ranks among students, and the gradebook files (no server)."""
from __future__ import annotations

import csv
import io
import re

import pytest
from pydantic import ValidationError

from league.server.course.grading import (
    CANVAS_STUDENT_COLUMNS, GENERIC_COLUMNS, MAX_FORMULA_CHARS, Entry, FormulaError, Graded, canvas_csv, course_csv,
    evaluate_formula, generic_csv, grade, moodle_csv, parse_formula, read_rubric,
)

FIGURES = {"completed": 0.5, "mean_speed": 2.0, "rank": 3, "students": 5}


def formula_rubric(formula: str, max_points: float = 10):
    return read_rubric({"kind": "formula", "max_points": max_points, "formula": formula})


def rubric_error(data: dict) -> str:
    with pytest.raises(ValidationError) as caught:
        read_rubric(data)
    return "; ".join(error["msg"] for error in caught.value.errors())


def rows_of(text: str) -> list[list[str]]:
    return list(csv.reader(io.StringIO(text)))


# --------------------------------------------------------------------------- formulas


@pytest.mark.parametrize("formula, value", [
    ("6 * completed + 4 * (students - rank) / (students - 1)", 3 + 2),
    ("10 if completed >= 0.5 else 0", 10),
    ("10 if 0.2 < completed < 0.5 else 1", 1),  # chained, as Python reads it
    ("completed > 0.4 and rank <= 3", 1),
    ("completed > 0.9 or 7", 7),
    ("(completed > 0.4) * 5 + (rank == 3)", 6),
    ("clip(mean_speed * 10, 0, 15)", 15),
    ("min(mean_speed, 1, 3) + max(rank, students)", 6),
    ("-completed + +2", 1.5),
    ("0.9 ** (rank - 1)", 0.81),
    ("2 ** -1", 0.5),
    ("1e3 * completed", 500),
])
def test_formulas_evaluate_as_written(formula, value):
    assert evaluate_formula(parse_formula(formula), FIGURES) == pytest.approx(value)


@pytest.mark.parametrize("formula, message", [
    ("__import__('os').system('true')", "the formula may call only min(), max(), clip()"),
    ("completed.real", "the formula may not use attributes (a.b)"),
    ("[1][0]", "the formula may not use indexing (a[b])"),
    ("x + 1", "unknown name 'x': the formula may use completed, mean_speed, rank, students"),
    ("min", "unknown name 'min'"),
    ("'10'", "the formula may use only numbers, not '10'"),
    ("True", "the formula may use only numbers, not True"),
    ("2j", "the formula may use only numbers, not 2j"),
    ("rank // 2", "the formula may not use //"),
    ("rank % 2", "the formula may not use %"),
    ("not rank", "the formula may not use not"),
    ("rank in (1, 2)", "the formula may not use `in` or `is`"),
    ("(lambda: 1)()", "the formula may call only min(), max(), clip()"),
    ("(x := 1)", "the formula may not use :="),
    ("clip(completed, 0)", "clip() takes 3 arguments (value, low, high), not 2"),
    ("max(rank)", "max() takes at least 2 arguments, not 1"),
    ("max(*[1, 2])", "max() takes plain arguments"),
    ("min(rank, key=1)", "min() takes plain arguments"),
    ("2 ** 1000", "an exponent is larger than 100"),
    ("rank = 1", "the formula is not an expression: invalid syntax"),
    ("1 if completed", "the formula is not an expression"),
    ("", "String should have at least 1 character"),
    ("1 +" * 200 + "1", f"String should have at most {MAX_FORMULA_CHARS} characters"),
])
def test_a_formula_outside_the_allow_list_is_refused_with_the_reason(formula, message):
    assert message in rubric_error({"kind": "formula", "max_points": 10, "formula": formula})


def test_formula_bounds_on_size_and_depth():
    with pytest.raises(FormulaError, match="more than 200 parts"):
        parse_formula("1+" * 110 + "1")
    with pytest.raises(FormulaError, match="nested deeper than 25 levels"):
        parse_formula("min(" * 30 + "rank, 1" + ", 1)" * 30)
    with pytest.raises(FormulaError, match=f"more than {MAX_FORMULA_CHARS}"):
        parse_formula("1" * (MAX_FORMULA_CHARS + 1))


@pytest.mark.parametrize("formula, message", [
    ("10 * completed / mean_speed", "divides by zero when completed=0, mean_speed=0, rank=1, students=1"),
    ("(students - rank) / (students - 1)", "divides by zero when completed=0, mean_speed=0, rank=1, students=1"),
    ("9 ** 9 ** 9", "overflows"),
    ("1e308 * 10 * (rank + 1)", "overflows"),
    ("(completed - 1) ** 0.5", "has no real value when completed=0"),
])
def test_a_formula_without_a_value_at_the_edges_is_refused_when_set(formula, message):
    """Every formula is evaluated at the edges (nothing completed, a car that never moved, one
    student, the last of thirty) when it is set: the instructor hears of it then, not at the due time."""
    assert message in rubric_error({"kind": "formula", "max_points": 10, "formula": formula})


# --------------------------------------------------------------------------- points rubrics


def test_points_by_completed_steps_and_by_rank_table():
    rubric = read_rubric({"kind": "points", "max_points": 10,
                          "completed": {"kind": "steps", "steps": [{"completed": 0.5, "points": 3},
                                                                   {"completed": 0.9, "points": 6}]},
                          "rank": {"kind": "table", "points": [4, 2, 1]}})
    points = [rubric.raw_points({"completed": c, "mean_speed": 1, "rank": r, "students": 9})
              for c, r in ((0.49, 4), (0.5, 3), (0.89, 2), (0.9, 1), (1.0, 9))]
    assert points == [0, 3 + 1, 3 + 2, 6 + 4, 6]


def test_points_linear_in_completed_fraction_and_in_rank():
    rubric = read_rubric({"kind": "points", "max_points": 10,
                          "completed": {"kind": "linear", "points": 6, "zero_at": 0.2, "full_at": 0.8},
                          "rank": {"kind": "linear", "points": 4}})
    assert rubric.raw_points({"completed": 0.5, "mean_speed": 1, "rank": 2, "students": 5}) == pytest.approx(3 + 3)
    assert rubric.raw_points({"completed": 0.1, "mean_speed": 1, "rank": 5, "students": 5}) == 0
    assert rubric.raw_points({"completed": 0.9, "mean_speed": 1, "rank": 1, "students": 1}) == 10  # alone: all


@pytest.mark.parametrize("data, message", [
    ({"kind": "points", "max_points": 10}, "give points by completed fraction, by rank, or both"),
    ({"kind": "points", "max_points": 5, "completed": {"kind": "linear", "points": 4},
      "rank": {"kind": "linear", "points": 2}}, "the parts give up to 6 points, more than max_points (5)"),
    ({"kind": "points", "max_points": 10, "completed": {"kind": "steps", "steps": [
        {"completed": 0.8, "points": 3}, {"completed": 0.5, "points": 5}]}}, "rising completed fractions"),
    ({"kind": "points", "max_points": 10, "completed": {"kind": "steps", "steps": [
        {"completed": 0.5, "points": 5}, {"completed": 0.8, "points": 3}]}}, "may not give fewer points"),
    ({"kind": "points", "max_points": 10, "completed": {"kind": "steps", "steps": [
        {"completed": 1.5, "points": 5}]}}, "less than or equal to 1"),
    ({"kind": "points", "max_points": 10, "completed": {"kind": "linear", "points": 5, "zero_at": 0.6,
                                                         "full_at": 0.5}}, "full_at must be above zero_at"),
    ({"kind": "points", "max_points": 10, "rank": {"kind": "table", "points": [1, 3]}}, "may not give more points"),
    ({"kind": "points", "max_points": 10, "rank": {"kind": "curve", "points": 3}},
     "does not match any of the expected"),
    ({"kind": "points", "max_points": 0, "rank": {"kind": "linear", "points": 0}}, "greater than 0"),
    ({"kind": "points", "max_points": 10, "rank": {"kind": "linear", "points": 3}, "bonus": 1}, "Extra inputs"),
    ({"kind": "magic", "max_points": 10}, "does not match any of the expected tags: 'points', 'formula'"),
])
def test_a_malformed_rubric_is_refused_with_the_reason(data, message):
    assert message in rubric_error(data)


def test_a_rubric_reads_back_from_its_json():
    for data in ({"kind": "formula", "max_points": 20.0, "formula": "20 * completed"},
                 {"kind": "points", "max_points": 10.0, "completed": {"kind": "linear", "points": 6.0,
                                                                     "zero_at": 0.0, "full_at": 1.0},
                  "rank": {"kind": "table", "points": [4.0, 2.0]}}):
        rubric = read_rubric(data)
        assert rubric.model_dump(mode="json") == data
        assert read_rubric(rubric.model_dump(mode="json")) == rubric


# --------------------------------------------------------------------------- grading

RANK_ONLY = {"kind": "points", "max_points": 10, "rank": {"kind": "table", "points": [10, 8, 6, 4]}}


def student(name: str, completed: float | None = 1.0, mean_return: float = 1.0, user_id: int = 0, **kw) -> Entry:
    kw.setdefault("submission_id", 100 + len(name))
    return Entry(name=name, user_id=user_id or hash(name) % 10_000 + 1, email=f"{name}@uni.example",
                 student_id=f"S-{name}", completed=completed,
                 mean_return=mean_return if completed is not None else None,
                 mean_speed=0.5 if completed is not None else None, **kw)


def baseline(name: str, completed: float, mean_return: float) -> Entry:
    return Entry(name=name, baseline=True, submission_id=1, completed=completed, mean_return=mean_return,
                 mean_speed=1.0)


def by_name(rows) -> dict:
    return {row.entry.name: row for row in rows}


def test_students_rank_among_students_only_and_baselines_are_reference_lines():
    """Issue 23: the first student had rank 4 (baselines took 1-3). Here baselines keep their place
    in the order, with their figures, and take neither a rank nor a grade."""
    rows = grade([baseline("ppo", 1.0, 9.0), baseline("sac", 1.0, 8.0), student("ann", 0.9), student("bob", 0.8),
                  baseline("td3", 0.85, 5.0)], read_rubric(RANK_ONLY))
    assert [(r.entry.name, r.rank, r.points) for r in rows] == [
        ("ppo", None, None), ("sac", None, None), ("ann", 1, 10), ("td3", None, None), ("bob", 2, 8)]
    assert rows[0].as_dict()["completed"] == 1.0 and rows[0].as_dict()["role"] == "baseline"


def test_equal_figures_share_a_rank_and_the_next_rank_is_skipped():
    rows = by_name(grade([student("ann", 0.9, 3.0), student("bob", 0.9, 3.0), student("cy", 0.9, 2.0),
                          student("dee", 0.5, 9.0)], read_rubric(RANK_ONLY)))
    assert [(rows[n].rank, rows[n].points) for n in ("ann", "bob", "cy", "dee")] == [(1, 10), (1, 10), (3, 6), (4, 4)]
    assert {rows[n].students for n in rows} == {4}


def test_a_revoked_student_is_flagged_and_moves_no_one():
    """A revoked student is graded where they would stand among the active students, and the
    active students' ranks are what they would be without them."""
    entries = [student("ann", 0.9), student("bob", 0.7), student("cy", 0.5)]
    without = by_name(grade(entries, read_rubric(RANK_ONLY)))
    rows = by_name(grade(entries + [student("rev", 0.8, revoked=True)], read_rubric(RANK_ONLY)))
    assert {n: rows[n].rank for n in without} == {n: without[n].rank for n in without} == {"ann": 1, "bob": 2, "cy": 3}
    assert (rows["rev"].rank, rows["rev"].students, rows["rev"].points) == (2, 4, 8)
    assert rows["rev"].as_dict()["revoked"] is True and rows["ann"].students == 3


def test_no_final_is_zero_and_a_final_without_a_private_result_is_empty():
    rows = grade([student("ann", 0.9), student("none", None, submission_id=None),
                  student("pending", None, submission_id=7), student("stale", None, submission_id=8, stale=True),
                  student("open", 1.0, closed=False)],
                 read_rubric(RANK_ONLY))
    assert [(r.entry.name, r.status, r.rank, r.penalty, r.points) for r in rows] == [
        ("ann", "graded", 1, 1.0, 10), ("open", "open", None, None, None), ("pending", "pending", None, None, None),
        ("stale", "stale", None, None, None), ("none", "no final", None, None, 0.0)]
    assert rows[0].students == 1  # nobody else was ranked


def test_the_late_penalty_multiplies_a_late_final_and_points_stay_within_zero_and_max():
    rubric = formula_rubric("12 * completed - 1", max_points=10)
    rows = by_name(grade([student("ann", 1.0), student("late", 1.0, late=True), student("low", 0.05),
                          student("half", 0.5, late=True)], rubric, late_penalty=0.75))
    assert [(rows[n].points, rows[n].penalty) for n in ("ann", "late", "low", "half")] == [
        (10, 1.0), (7.5, 0.75), (0, 1.0), (3.75, 0.75)]
    no_policy = by_name(grade([student("late", 1.0, late=True)], rubric))
    assert no_policy["late"].points == 10


def test_a_formula_that_fails_for_some_student_says_for_which_figures():
    """The edges are checked when the rubric is set; a value only some student has is caught when grading."""
    rubric = formula_rubric("1 if mean_speed != 0.25 else 1 / (mean_speed - 0.25)")
    assert grade([student("ann")], rubric)[0].points == 1
    with pytest.raises(FormulaError, match="divides by zero when completed=1, mean_speed=0.25, rank=1, students=1"):
        grade([Entry("ann", 1, submission_id=1, completed=1.0, mean_return=1.0, mean_speed=0.25)], rubric)


# --------------------------------------------------------------------------- exports


def graded_rows():
    return grade([student("ann", 0.9, user_id=1), student("bob", 0.6, late=True, user_id=2),
                  student("=HYPERLINK(\"x\")", 0.3, user_id=3), student("none", None, submission_id=None, user_id=4),
                  student("pending", None, submission_id=9, user_id=5), student("rev", 0.95, revoked=True, user_id=6),
                  baseline("ppo", 1.0, 5.0)], read_rubric(RANK_ONLY), late_penalty=0.5)


def test_the_generic_csv_has_every_column_and_baselines_as_reference_lines():
    lines = rows_of(generic_csv(graded_rows()))
    assert lines[0] == GENERIC_COLUMNS
    table = {line[0]: dict(zip(GENERIC_COLUMNS, line)) for line in lines[1:]}
    assert table["ann"] == {**table["ann"], "role": "student", "email": "ann@uni.example",
                                 "student_id": "S-ann", "completed": "0.9", "rank": "1", "students": "3",
                                 "late": "", "penalty": "1.0", "points": "10.0", "revoked": ""}
    assert (table["bob"]["late"], table["bob"]["penalty"], table["bob"]["points"]) == ("yes", "0.5", "4.0")
    assert (table["ppo"]["role"], table["ppo"]["rank"], table["ppo"]["points"]) == ("baseline", "", "")
    assert (table["rev"]["revoked"], table["rev"]["rank"]) == ("yes", "1")
    assert (table["none"]["submission"], table["none"]["points"]) == ("", "0.0")
    assert (table["pending"]["submission"], table["pending"]["points"]) == ("9", "")
    assert "'=HYPERLINK(\"x\")" in table  # a name is never a formula


def test_the_canvas_file_has_the_columns_canvas_reads_and_the_points_possible_row():
    """Canvas's importer wants Student, ID, SIS User ID, SIS Login ID, Section, then one column an
    assignment; a row whose first cell says Points Possible gives the maximum. Baselines are not
    students of the course and are not in it."""
    graded = Graded("Time trial", 10, graded_rows())
    lines = rows_of(canvas_csv([graded, Graded("Obstacles", 20, graded_rows())]))
    header = lines[0]
    assert header == CANVAS_STUDENT_COLUMNS + ["Time trial", "Obstacles"]
    assert re.search("Student", header[0]) and re.search("ID", header[1]) and re.search(r"SIS\s+User\s+ID", header[2])
    assert re.search(r"SIS\s+Login\s+ID", header[3]) and re.search("Section", header[4])
    assert lines[1] == ["Points Possible", "", "", "", "", "10", "20"]
    students = {line[0]: line for line in lines[2:]}
    assert set(students) == {"ann", "bob", "'=HYPERLINK(\"x\")", "none", "pending", "rev"}
    assert students["ann"] == ["ann", "", "S-ann", "ann@uni.example", "", "10.0", "10.0"]
    assert students["pending"][5:] == ["", ""] and students["none"][5:] == ["0.0", "0.0"]


def test_the_moodle_file_has_an_identifier_and_a_grade_column_and_leaves_out_who_it_cannot_identify():
    graded = [Graded("Time trial", 10, graded_rows())]
    text, left_out = moodle_csv(graded)
    lines = rows_of(text)
    assert lines[0] == ["Email address", "Time trial"]
    assert dict(lines[1:])["bob@uni.example"] == "4.0" and left_out == []
    anonymous = [Graded("T", 10, grade([student("ann"), Entry("nomail", 9, submission_id=None)],
                                       read_rubric(RANK_ONLY)))]
    text, left_out = moodle_csv(anonymous, identifier="idnumber")
    assert rows_of(text) == [["ID number", "T"], ["S-ann", "10.0"]] and left_out == ["nomail"]


def test_the_course_file_has_a_column_an_assignment_and_a_total_that_waits_for_pending_grades():
    first = Graded("A1", 10, graded_rows())
    second = Graded("A2", 5, grade([student("ann", 0.1, user_id=1), student("bob", 1.0, user_id=2)],
                                   read_rubric({"kind": "formula", "max_points": 5, "formula": "5 * completed"})))
    lines = rows_of(course_csv([first, second]))
    assert lines[0] == ["name", "email", "student_id", "revoked", "A1", "A2", "total"]
    assert lines[1] == ["Points Possible", "", "", "", "10", "5", "15"]
    table = {line[0]: line[4:] for line in lines[2:]}
    assert table["ann"] == ["10.0", "0.5", "10.5"] and table["bob"] == ["4.0", "5.0", "9.0"]
    assert table["pending"] == ["", "", ""] and table["rev"] == ["10.0", "", ""]
