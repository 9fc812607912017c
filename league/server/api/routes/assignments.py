"""Assignments: their times and tracks, extensions, final selections, publication, and their boards."""
from __future__ import annotations

from typing import Annotated, Literal

from fastapi import APIRouter, HTTPException, Query, Request, Response, status
from fastapi.concurrency import run_in_threadpool
from pydantic import ValidationError

from league.server.api.cache import PRIVATE as PRIVATE_CACHE, PUBLIC as PUBLIC_CACHE, cached_json
from league.server.course import audit
from league.server.api.deps import (
    CacheDep, ClockDep, CurrentUser, Id, InstructorUser, OptionalUser, PageNumber, PageSize, QueueDep, SessionDep,
    SessionsDep, SettingsDep, board_course, board_names, check_env_options, csv_response, user_course,
)
from league.server.course.assignments import (
    UploadRefused, final_choices, private_visible, publish, select_final, user_window,
)
from league.server.course.results import change_settings
from league.server.db import crud
from league.server.db.models import PRIVATE_TRACKS, PUBLIC_TRACKS, STUDENT, Assignment, Evaluation, User
from league.server.api.schemas import (
    AssignmentBoard, AssignmentCreate, AssignmentOut, AssignmentTimes, AssignmentUpdate, EvaluationOut, ExtensionIn,
    ExtensionOut, FinalOut, SelectionIn,
)
from league.server.course.standings import LEADERBOARD_GRADES, assignment_board, grade_rows

router = APIRouter(prefix="/assignments", tags=["assignments"])
Board = Annotated[Literal["public", "private"], Query(description="private: once the assignment is published")]
SETTINGS = ("seed", "episodes", "env_options")
TIMES = tuple(AssignmentTimes.model_fields)
AUDITED = ("name", *SETTINGS, *TIMES)  # what the audit log keeps of an assignment's creation and edits


def refused(error: UploadRefused) -> HTTPException:
    return HTTPException(error.status, str(error))


def course_assignment(session: SessionDep, user: User, assignment_id: int) -> Assignment:
    assignment = session.get(Assignment, assignment_id)
    if assignment is None or assignment.course_id != user_course(session, user).id:
        raise HTTPException(status.HTTP_404_NOT_FOUND, "no such assignment in your course")
    return assignment


def assignment_out(session: SessionDep, assignment: Assignment, user: User, clock: ClockDep) -> AssignmentOut:
    """The assignment as `user` may see it: private seed and results only once published (instructors:
    always); a student's own times and final."""
    now = clock.now()
    row = crud.student_assignment(session, assignment_id=assignment.id, user_id=user.id)
    times, visible = user_window(session, assignment, user), private_visible(assignment, user)
    final = None
    if user.role == STUDENT:
        chosen = final_choices(session, assignment, [user.id])[user.id]
        evaluation = row and row.final_evaluation_id and visible and session.get(Evaluation, row.final_evaluation_id)
        final = FinalOut(submission_id=chosen, selected=bool(row and row.selected_submission_id == chosen and chosen),
                         frozen_at=row.final_at if row else None, decided=bool(row and row.final_decided_at),
                         evaluation=EvaluationOut.model_validate(evaluation) if evaluation else None)
    return AssignmentOut(
        **{name: getattr(assignment, name) for name in ("id", "name", "description", *SETTINGS, *TIMES,
                                                        "published_at", "rubric", "automatic", "keep_open")},
        private_seed=assignment.private_seed if visible else None, my_due_at=times.due_at,
        my_closes_at=times.closes_at, extended=times.extended, state=times.state(now), now=now, final=final)


@router.get("", response_model=list[AssignmentOut])
def read_assignments(clock: ClockDep, user: CurrentUser, session: SessionDep) -> list[AssignmentOut]:
    """Your course's assignments, oldest first, with your own due time, state and final."""
    course = user_course(session, user)
    return [assignment_out(session, a, user, clock) for a in crud.course_assignments(session, course_id=course.id)]


@router.post("", response_model=AssignmentOut, status_code=status.HTTP_201_CREATED)
def create_assignment(body: AssignmentCreate, clock: ClockDep, instructor: InstructorUser, session: SessionDep,
                      queue: QueueDep, settings: SettingsDep) -> AssignmentOut:
    """A new assignment of your course (its private seed drawn by the server); the baselines are
    evaluated on its public tracks, after the students' jobs."""
    check_env_options(body.env_options)
    course = user_course(session, instructor)
    check_name_free(session, course.id, body.name)
    assignment = crud.create_assignment(session, course=course, name=body.name, description=body.description,
                                        **body.model_dump(include=set(SETTINGS) | set(TIMES)))
    change = change_settings(session, assignment=assignment, settings=assignment.evaluation_settings(),
                             max_attempts=settings.max_job_attempts, unchanged="")
    session.flush()
    audit.record(session, actor=instructor, action=audit.CREATE_ASSIGNMENT, target_kind="assignment",
                 target_id=assignment.id, before={}, after=audit.snapshot(assignment, AUDITED))
    session.commit()
    for job in change.queued:
        queue.enqueue(job.id)
    return assignment_out(session, assignment, instructor, clock)


def check_name_free(session: SessionDep, course_id: int, name: str, other_than: int | None = None) -> None:
    for assignment in crud.course_assignments(session, course_id=course_id):
        if assignment.name == name and assignment.id != other_than:
            raise HTTPException(status.HTTP_409_CONFLICT, f"the course has an assignment named {name!r} already")


@router.get("/{assignment_id}", response_model=AssignmentOut)
def read_assignment(assignment_id: Id, clock: ClockDep, user: CurrentUser, session: SessionDep) -> AssignmentOut:
    """One assignment, as in the list."""
    return assignment_out(session, course_assignment(session, user, assignment_id), user, clock)


@router.patch("/{assignment_id}", response_model=AssignmentOut)
def update_assignment(assignment_id: Id, body: AssignmentUpdate, clock: ClockDep, instructor: InstructorUser,
                      session: SessionDep, queue: QueueDep, settings: SettingsDep) -> AssignmentOut:
    """Edit an assignment (only the fields sent). New public settings make its results of others stale
    and re-evaluate its submissions after the students' jobs; finals already frozen stay."""
    assignment = course_assignment(session, instructor, assignment_id)
    before = audit.snapshot(assignment, AUDITED)
    sent = body.model_dump(exclude_unset=True)
    times = {name: sent.get(name, getattr(assignment, name)) for name in TIMES}
    try:
        AssignmentTimes.model_validate({**times, "auto_publish": bool(times["auto_publish"])})
    except ValidationError as error:
        raise HTTPException(status.HTTP_422_UNPROCESSABLE_CONTENT, error.errors()[0]["msg"]) from None
    if "name" in sent:
        check_name_free(session, assignment.course_id, sent["name"], other_than=assignment.id)
    if sent.get("keep_open") is not None:
        if not assignment.automatic:
            raise HTTPException(status.HTTP_422_UNPROCESSABLE_CONTENT,
                                f"keep_open is the course's automatic assignment's only: {assignment.name} takes "
                                "uploads by its own times")
        assignment.keep_open = sent["keep_open"]
    for name in ("name", "description", *TIMES):
        if name in sent and (sent[name] is not None or name in TIMES):
            setattr(assignment, name, sent[name] if name != "auto_publish" else bool(sent[name]))
    wanted = {**assignment.evaluation_settings(), **{k: v for k, v in sent.items() if k in SETTINGS and v is not None}}
    check_env_options(wanted["env_options"])
    change = change_settings(session, assignment=assignment, settings=wanted, max_attempts=settings.max_job_attempts)
    changed = audit.changes(before, audit.snapshot(assignment, AUDITED))
    if changed["after"]:
        audit.record(session, actor=instructor, action=audit.EDIT_ASSIGNMENT, target_kind="assignment",
                     target_id=assignment.id, **changed, reevaluating=len(change.queued))
    session.commit()
    for job in change.queued:
        queue.enqueue(job.id)
    return assignment_out(session, assignment, instructor, clock)


@router.put("/{assignment_id}/extensions/{user_id}", response_model=ExtensionOut)
def set_extension(assignment_id: Id, user_id: Id, body: ExtensionIn, instructor: InstructorUser,
                  session: SessionDep) -> ExtensionOut:
    """Give a student their own due time (the late window, if any, still ends at late_until)."""
    assignment, student = extension_parties(session, instructor, assignment_id, user_id)
    row = crud.student_assignment(session, assignment_id=assignment.id, user_id=student.id, create=True)
    record_extension(session, instructor, row, body.due_at)
    session.commit()
    return ExtensionOut(assignment_id=assignment.id, user_id=student.id, due_at=row.extension_due_at)


@router.delete("/{assignment_id}/extensions/{user_id}", response_model=ExtensionOut)
def delete_extension(assignment_id: Id, user_id: Id, instructor: InstructorUser, session: SessionDep) -> ExtensionOut:
    """Back to the assignment's due time."""
    assignment, student = extension_parties(session, instructor, assignment_id, user_id)
    row = crud.student_assignment(session, assignment_id=assignment.id, user_id=student.id)
    if row is not None and row.extension_due_at is not None:
        record_extension(session, instructor, row, None)
        session.commit()
    return ExtensionOut(assignment_id=assignment.id, user_id=student.id, due_at=None)


def record_extension(session: SessionDep, instructor: User, row, due_at) -> None:
    """Set the student's own due time (None: the assignment's) and log it (the student by id only:
    their name would outlive their erasure)."""
    before = audit.snapshot(row, ["extension_due_at"])
    row.extension_due_at = due_at
    audit.record(session, actor=instructor, action=audit.EXTENSION, target_kind="user", target_id=row.user_id,
                 assignment_id=row.assignment_id, **audit.changes(before, audit.snapshot(row, ["extension_due_at"])))


def extension_parties(session: SessionDep, instructor: User, assignment_id: int, user_id: int):
    assignment = course_assignment(session, instructor, assignment_id)
    student = session.get(User, user_id)
    if student is None or student.role != STUDENT or student.course_id != assignment.course_id:
        raise HTTPException(status.HTTP_404_NOT_FOUND, "no such student in your course")
    row = crud.student_assignment(session, assignment_id=assignment.id, user_id=student.id)
    if row is not None and row.final_at is not None:
        raise HTTPException(status.HTTP_409_CONFLICT, f"{student.name}'s final of {assignment.name} was frozen at "
                                                      f"{row.final_at.isoformat(timespec='seconds')}")
    return assignment, student


@router.post("/{assignment_id}/selection", response_model=AssignmentOut)
def select_submission(assignment_id: Id, body: SelectionIn, clock: ClockDep, user: CurrentUser,
                      session: SessionDep) -> AssignmentOut:
    """Select your final submission (a ready one of yours in the assignment; null: your best on the
    public board), until your close time."""
    assignment = course_assignment(session, user, assignment_id)
    if user.role != STUDENT:
        raise HTTPException(status.HTTP_403_FORBIDDEN, "only students select a final submission")
    try:
        select_final(session, assignment=assignment, user=user, submission_id=body.submission_id,
                     now=clock.now())
    except UploadRefused as error:
        raise refused(error) from None
    session.commit()
    return assignment_out(session, assignment, user, clock)


@router.post("/{assignment_id}/publish", response_model=AssignmentOut)
def publish_assignment(assignment_id: Id, clock: ClockDep, instructor: InstructorUser,
                       session: SessionDep) -> AssignmentOut:
    """Show the private board, seed and tracks to the students (once every student's close time has passed)."""
    assignment = course_assignment(session, instructor, assignment_id)
    before = audit.snapshot(assignment, ["published_at"])
    try:
        publish(session, assignment=assignment, now=clock.now())
    except UploadRefused as error:
        raise refused(error) from None
    if before["published_at"] is None:
        audit.record(session, actor=instructor, action=audit.PUBLISH, target_kind="assignment",
                     target_id=assignment.id, **audit.changes(before, audit.snapshot(assignment, ["published_at"])))
    session.commit()
    return assignment_out(session, assignment, instructor, clock)


def board_rows(session: SessionDep, assignment: Assignment, board: str) -> list[dict]:
    if board == "private" and assignment.published_at is None:
        raise HTTPException(status.HTTP_404_NOT_FOUND, f"the private board of {assignment.name} is not published")
    return assignment_board(session, assignment, PRIVATE_TRACKS if board == "private" else PUBLIC_TRACKS)


@router.get("/{assignment_id}/board", response_model=AssignmentBoard)
async def read_board(assignment_id: Id, request: Request, viewer: OptionalUser, session: SessionDep,
                     sessions: SessionsDep, cache: CacheDep, board: Board = "public", page: PageNumber = 1,
                     size: PageSize = 50) -> Response:
    """The assignment's board, best first (as /api/leaderboard, and shown as its course's board
    visibility allows): public (its public tracks), or private (the students' finals on its private
    tracks) once published."""

    def check():
        assignment = session.get(Assignment, assignment_id)
        if assignment is None:
            raise HTTPException(status.HTTP_404_NOT_FOUND, "no such assignment")
        return board_names(session, viewer, board_course(session, viewer, assignment.course_id))

    names = await run_in_threadpool(check)

    def compute() -> bytes:
        with sessions() as compute_session:
            rows = names.rows(board_rows(compute_session, compute_session.get(Assignment, assignment_id), board))
        return AssignmentBoard(board=board, items=rows[(page - 1) * size: page * size],
                               total=len(rows)).model_dump_json().encode()

    key = ("assignment-board", assignment_id, board, names.real, page, size)
    return await cached_json(request, cache, sessions, key, compute, PRIVATE_CACHE if names.real else PUBLIC_CACHE)


@router.get("/{assignment_id}/board.csv", response_class=Response, responses={200: {"content": {"text/csv": {}}}})
def read_board_csv(assignment_id: Id, session: SessionDep, instructor: InstructorUser,
                   board: Board = "public") -> Response:
    """The board as grades (instructors): one line per student of your course, as /api/leaderboard.csv.
    The private board: before publication too (instructors see it)."""
    assignment = course_assignment(session, instructor, assignment_id)
    track = PRIVATE_TRACKS if board == "private" else PUBLIC_TRACKS
    rows = grade_rows(session, assignment_board(session, assignment, track), course_id=assignment.course_id,
                      columns=LEADERBOARD_GRADES)
    return csv_response(LEADERBOARD_GRADES, rows, f"{assignment.name}-{board}.csv")
