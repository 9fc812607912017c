"""Privacy: who sees the course's boards (instructors set it), and a student's display name."""
from __future__ import annotations

from fastapi import APIRouter, HTTPException, status
from sqlalchemy.exc import IntegrityError

from league.server.api.deps import CurrentUser, InstructorUser, SessionDep, SettingsDep, user_course
from league.server.api.routes.users import read_me
from league.server.api.schemas import PrivacySettings, UserMe, UserUpdate
from league.server.course import audit
from league.server.db import crud

router = APIRouter(tags=["privacy"])


@router.get("/settings/privacy", response_model=PrivacySettings)
def read_privacy_settings(user: CurrentUser, session: SessionDep) -> PrivacySettings:
    """Who sees your course's boards."""
    return PrivacySettings(board_visibility=user_course(session, user).board_visibility)


@router.put("/settings/privacy", response_model=PrivacySettings)
def update_privacy_settings(body: PrivacySettings, instructor: InstructorUser, session: SessionDep) -> PrivacySettings:
    """Choose who sees the course's boards: it applies to the next request of every route and page."""
    course = user_course(session, instructor)
    audit.record(session, actor=instructor, action=audit.PRIVACY, target_kind="course", target_id=course.id,
                 course_id=course.id, board_visibility=body.board_visibility, was=course.board_visibility)
    course.board_visibility = body.board_visibility
    session.commit()
    return PrivacySettings(board_visibility=course.board_visibility)


@router.patch("/users/me", response_model=UserMe)
def update_me(body: UserUpdate, user: CurrentUser, session: SessionDep, settings: SettingsDep) -> UserMe:
    """Choose the display name that public boards show visitors instead of your name (null: none)."""
    try:
        crud.set_display_name(session, user=user, display_name=body.display_name)
        session.commit()
    except crud.AccountTaken as error:
        raise HTTPException(status.HTTP_409_CONFLICT, str(error)) from error
    except crud.InvalidAccount as error:
        raise HTTPException(status.HTTP_422_UNPROCESSABLE_CONTENT, str(error)) from error
    except IntegrityError as error:  # another student took it at the same moment
        raise HTTPException(status.HTTP_409_CONFLICT, f"the display name {body.display_name!r} is taken: "
                                                      "choose another") from error
    return read_me(user, session, settings)
