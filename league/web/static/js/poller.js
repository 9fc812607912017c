// Run a task now and then again every `interval` ms, one at a time, paused while the tab is hidden.
// The task may return false to stop; `poll()` runs it at once (e.g. after an upload) and resumes.

export class Poller {
  constructor(task, interval) {
    this.task = task;
    this.interval = interval;
    this.timer = null;
    this.running = false;
    this.stopped = true;
    document.addEventListener("visibilitychange", () => {
      if (!document.hidden && !this.stopped) this.poll();
    });
  }

  async poll() {
    this.stopped = false;
    clearTimeout(this.timer);
    if (this.running) {
      this.rerun = true; // the running task may have read the old state: run again when it ends
      return;
    }
    this.running = true;
    this.rerun = false;
    let again = true;
    try {
      again = (await this.task()) !== false;
    } catch (error) {
      console.error(error);
    } finally {
      this.running = false;
    }
    if (!again && !this.rerun) this.stopped = true;
    if (this.stopped || document.hidden) return;
    this.timer = setTimeout(() => this.poll(), this.rerun ? 0 : this.interval);
  }

  stop() {
    this.stopped = true;
    clearTimeout(this.timer);
  }
}
