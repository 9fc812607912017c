// A race replay of the toolkit (league.evaluation.race(...).replay, format "microracer-replay",
// version 1): per car, x / y / heading / speed at the start and after each step, and each step's
// action (acc, turn); the classification; the track in compact form.

import { actionText, finalText } from "./format.js";

export const REPLAY_FORMAT = "microracer-replay";
export const REPLAY_VERSION = 1;

export class Replay {
  /** Throws an Error saying what is wrong when `data` is not a replay this viewer plays. */
  constructor(data) {
    if (!data || typeof data !== "object" || data.format !== REPLAY_FORMAT) {
      throw new Error(`not a MicroRacer replay (no "format": "${REPLAY_FORMAT}")`);
    }
    if (data.version !== REPLAY_VERSION) {
      throw new Error(`a replay of version ${data.version}; this viewer plays version ${REPLAY_VERSION}`);
    }
    if (!Array.isArray(data.cars) || !data.cars.length || !data.track) throw new Error("the replay has no cars or no track");
    this.data = data;
    this.cars = data.cars;
    this.names = data.names || this.cars.map((_, i) => `car ${i + 1}`);
    this.tstep = data.tstep;
    this.lastStep = this.cars.map((car) => car.x.length - 1); // each car's final step
    this.totalSteps = Math.max(...this.lastStep);
    this.rows = Object.fromEntries((data.classification || []).map((row) => [row.car, row]));
  }

  get carCount() {
    return this.cars.length;
  }

  /** Where car `i` is at `step` (a car that stopped stays where it stopped). */
  position(i, step) {
    const car = this.cars[i];
    const k = Math.min(step, this.lastStep[i]);
    return { x: car.x[k], y: car.y[k], heading: car.heading[k] };
  }

  /** The legend line of car `i` at `step`: its action and speed while it drives, then its result. */
  legend(i, step) {
    const car = this.cars[i];
    if (step < this.lastStep[i]) {
      return { text: actionText(car.acc[step], car.turn[step], car.speed[step]), final: false };
    }
    const row = this.rows[`car_${i}`];
    return { text: row ? finalText(row) : "stopped", final: true };
  }

  seconds(step) {
    return Math.min(step, this.totalSteps) * this.tstep;
  }
}
