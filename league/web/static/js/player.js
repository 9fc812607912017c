// Plays a replay in (scaled) race time: `speed` 1 is real time, 1 / tstep steps a second.
// Reports each new whole step to `onStep(step)` and play/pause changes to `onState(playing)`.

export class Player {
  constructor({ totalSteps, stepsPerSecond, onStep, onState }) {
    this.totalSteps = totalSteps;
    this.stepsPerSecond = stepsPerSecond;
    this.onStep = onStep;
    this.onState = onState;
    this.position = 0; // fractional step
    this.speed = 1;
    this.playing = false;
    this.lastTime = null;
    this.frame = this.frame.bind(this);
  }

  get step() {
    return Math.floor(this.position);
  }

  play() {
    if (this.playing) return;
    if (this.step >= this.totalSteps) this.position = 0; // replay from the start
    this.playing = true;
    this.lastTime = null;
    this.onState(true);
    requestAnimationFrame(this.frame);
  }

  pause() {
    if (!this.playing) return;
    this.playing = false;
    this.onState(false);
  }

  toggle() {
    if (this.playing) this.pause();
    else this.play();
  }

  seek(step) {
    const before = this.step;
    this.position = Math.min(Math.max(Math.round(step), 0), this.totalSteps);
    if (this.step !== before || !this.playing) this.onStep(this.step);
  }

  frame(time) {
    if (!this.playing) return;
    if (this.lastTime !== null) {
      const before = this.step;
      const elapsed = Math.min((time - this.lastTime) / 1000, 0.25); // a background tab does not jump ahead
      this.position = Math.min(this.position + elapsed * this.stepsPerSecond * this.speed, this.totalSteps);
      if (this.step !== before) this.onStep(this.step);
      if (this.step >= this.totalSteps) {
        this.pause();
        return;
      }
    }
    this.lastTime = time;
    requestAnimationFrame(this.frame);
  }
}
