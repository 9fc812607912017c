// The status words of submissions, evaluations, jobs, races and championship rounds, and their groups, as
// the API answers them: the server's table (league.statuses), handed to every page by the layout.
export const {
  PENDING, VALIDATING, READY, REJECTED, FAILED, QUEUED, RUNNING, DONE, // the words
  VALIDATED, // a submission's once its validation is over
  ENDED, // an evaluation's, a job's, a race's or a round's once over
} = JSON.parse(document.body.dataset.statuses);
