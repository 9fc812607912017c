"""Grades: an assignment's rubric, its grades on the private tracks (JSON and the gradebooks' CSVs),
a student's own grade once published, and the course's grades (league.server.course.grading holds the rules)."""
from __future__ import annotations

from typing import Annotated, Literal

from fastapi import APIRouter, Body, HTTPException, Query, Response, status

from league.server.course import audit, grading
from league.server.api.deps import (
    ClockDep, CurrentUser, Id, InstructorUser, QueueDep, SessionDep, SettingsDep, user_course,
)
from league.server.api.routes.assignments import assignment_out, course_assignment
from league.server.api.schemas import AssignmentOut, CanvasMatchOut, GradesOut, MyGradeOut
from league.server.course.assignment_grades import NoRubric, assignment_grades, queue_missing_evaluations, rubric_of
from league.server.db import crud
from league.server.db.models import STUDENT, Assignment

router = APIRouter(tags=["grades"])
Format = Annotated[Literal["generic", "canvas", "moodle"], Query(
    description="generic: every column; canvas, moodle: their gradebooks' CSV import (server README, Grades)")]
Identifier = Annotated[Literal["email", "idnumber"], Query(
    description="moodle: the user field Moodle matches students by (students without it are left out)")]
RubricBody = Annotated[grading.PointsRubric | grading.FormulaRubric, Body(discriminator="kind")]
CSV = {200: {"content": {"text/csv": {}}}}


def graded_or_409(session: SessionDep, assignment: Assignment) -> grading.Graded:
    """The assignment's grades, or 409 saying what to do (no rubric; a formula without a value for
    some student's figures)."""
    try:
        return grading.Graded(assignment.name, rubric_of(assignment).max_points, assignment_grades(session, assignment))
    except NoRubric as error:
        raise HTTPException(status.HTTP_409_CONFLICT, str(error)) from None
    except grading.FormulaError as error:
        raise HTTPException(status.HTTP_409_CONFLICT, f"{assignment.name}: {error}: set another rubric") from None


def csv_file(graded: list[grading.Graded], fmt: str, identifier: str, stem: str, generic: str) -> Response:
    """The file of `fmt`: Canvas's or Moodle's import, else the `generic` text. A Moodle file's
    `X-Left-Out` header counts the students it leaves out (without the identifier)."""
    suffix = "" if fmt == "generic" else f"-{fmt}"
    headers, text = {"Content-Disposition": f'attachment; filename="{stem}{suffix}.csv"'}, generic
    if fmt == "canvas":
        text = grading.canvas_csv(graded)
    elif fmt == "moodle":
        text, left_out = grading.moodle_csv(graded, identifier=identifier)
        headers["X-Left-Out"] = str(len(left_out))
    return Response(text, media_type="text/csv; charset=utf-8", headers=headers)


@router.put("/assignments/{assignment_id}/rubric", response_model=AssignmentOut)
def set_rubric(assignment_id: Id, body: RubricBody, clock: ClockDep, instructor: InstructorUser, session: SessionDep,
               queue: QueueDep, settings: SettingsDep) -> AssignmentOut:
    """Set how the assignment is graded (checked: a 422 says what to change). The private evaluations
    the grades lack are queued at low priority: the baselines' (reference lines), and after a change
    of the assignment's settings, the finals evaluated with the old ones."""
    assignment = course_assignment(session, instructor, assignment_id)
    before = audit.snapshot(assignment, ["rubric"])
    assignment.rubric = body.model_dump(mode="json")
    changed = audit.changes(before, audit.snapshot(assignment, ["rubric"]))
    if changed["after"]:
        audit.record(session, actor=instructor, action=audit.RUBRIC, target_kind="assignment",
                     target_id=assignment.id, **changed)
    jobs = queue_missing_evaluations(session, assignment=assignment, max_attempts=settings.max_job_attempts)
    session.commit()
    for job in jobs:
        queue.enqueue(job.id)
    return assignment_out(session, assignment, instructor, clock)


@router.get("/assignments/{assignment_id}/grades", response_model=GradesOut)
def read_grades(assignment_id: Id, instructor: InstructorUser, session: SessionDep) -> GradesOut:
    """The assignment's grades (instructors, before and after publication): every student of your
    course on their final's private result, under the rubric, with the late penalty."""
    assignment = course_assignment(session, instructor, assignment_id)
    graded = graded_or_409(session, assignment)
    return GradesOut(assignment_id=assignment.id, assignment=assignment.name,
                     published=assignment.published_at is not None, max_points=graded.max_points,
                     late_penalty=assignment.late_penalty, rubric=assignment.rubric,
                     rows=[row.as_dict() for row in graded.rows])


@router.get("/assignments/{assignment_id}/grades.csv", response_class=Response, responses=CSV)
def read_grades_csv(assignment_id: Id, instructor: InstructorUser, session: SessionDep, format: Format = "generic",
                    identifier: Identifier = "email") -> Response:
    """The grades as a file (instructors): generic (every column, baselines as reference lines), or
    Canvas's or Moodle's gradebook import."""
    assignment = course_assignment(session, instructor, assignment_id)
    graded = graded_or_409(session, assignment)
    return csv_file([graded], format, identifier, f"grades-{assignment.id}", grading.generic_csv(graded.rows))


@router.get("/assignments/{assignment_id}/grades/me", response_model=MyGradeOut)
def read_my_grade(assignment_id: Id, user: CurrentUser, session: SessionDep) -> MyGradeOut:
    """Your grade (students), once the assignment is published."""
    assignment = course_assignment(session, user, assignment_id)
    if user.role != STUDENT:
        raise HTTPException(status.HTTP_403_FORBIDDEN, "only students have a grade: see /grades")
    if assignment.published_at is None:
        raise HTTPException(status.HTTP_404_NOT_FOUND, f"the grades of {assignment.name} are not published")
    graded = graded_or_409(session, assignment)
    mine = next(row for row in graded.rows if row.entry.user_id == user.id)
    return MyGradeOut(**mine.as_dict(), assignment_id=assignment.id, assignment=assignment.name,
                      max_points=graded.max_points)


@router.get("/grades.csv", response_class=Response, responses=CSV)
def read_course_grades_csv(instructor: InstructorUser, session: SessionDep, format: Format = "generic",
                           identifier: Identifier = "email") -> Response:
    """The course's grades (instructors): a line a student, a column for each assignment that has a
    rubric, and the total (generic); or Canvas's or Moodle's import of those columns."""
    graded = course_graded(session, instructor)
    return csv_file(graded, format, identifier, "grades", grading.course_csv(graded))


def course_graded(session: SessionDep, instructor: InstructorUser) -> list[grading.Graded]:
    """The grades of each assignment of the course that has a rubric (409 if none has)."""
    course = user_course(session, instructor)
    graded = [graded_or_409(session, a) for a in crud.course_assignments(session, course_id=course.id)
              if a.rubric is not None]
    if not graded:
        raise HTTPException(status.HTTP_409_CONFLICT, "no assignment has a rubric yet: set one "
                                                      "(PUT /api/assignments/{id}/rubric)")
    return graded


def canvas_match_out(graded: list[grading.Graded]) -> CanvasMatchOut:
    match = grading.canvas_match(graded)
    return CanvasMatchOut(students=match.students, by_id=match.by_id, by_email=match.by_email,
                          by_name=match.by_name, summary=match.summary())


@router.get("/assignments/{assignment_id}/grades/canvas-match", response_model=CanvasMatchOut)
def read_canvas_match(assignment_id: Id, instructor: InstructorUser, session: SessionDep) -> CanvasMatchOut:
    """Before importing the assignment's Canvas file (instructors): how many of its lines carry an id
    Canvas matches students by, and who would be matched only by email or by name."""
    assignment = course_assignment(session, instructor, assignment_id)
    return canvas_match_out([graded_or_409(session, assignment)])


@router.get("/grades/canvas-match", response_model=CanvasMatchOut)
def read_course_canvas_match(instructor: InstructorUser, session: SessionDep) -> CanvasMatchOut:
    """The same for the course's Canvas file (every assignment with a rubric)."""
    return canvas_match_out(course_graded(session, instructor))
