"""The course domain: courses and their people (courses, accounts, roster, privacy, erasure, audit),
assignments and their finals (assignments), which results count (results), grades (grading: the
rules; assignment_grades: an assignment's grades from the database), races and championship rounds
(races, standings) and the integrity report (integrity). The API's routes, the jobs and the CLI
call these; the rules live here once."""
