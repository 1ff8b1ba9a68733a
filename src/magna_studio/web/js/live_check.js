// Live validation: after each edit, one check request once typing pauses, and only the newest answer is used
// (an older request that returns late must not overwrite a newer result).

export const CHECK_DELAY_MS = 300;

export class LiveCheck {
  /** `run()` returns a promise of the check's answer; `apply(answer)` shows it; `fail(error)` reports. */
  constructor(run, apply, fail, delay = CHECK_DELAY_MS) {
    this.run = run;
    this.apply = apply;
    this.fail = fail;
    this.delay = delay;
    this.timer = null;
    this.latest = 0;
  }

  /** Check after the pause (each call restarts it). */
  schedule() {
    clearTimeout(this.timer);
    this.timer = setTimeout(() => this.now(), this.delay);
  }

  /** Check at once; resolves when this check's answer (if still the newest) is shown. */
  async now() {
    clearTimeout(this.timer);
    const ticket = ++this.latest;
    try {
      const answer = await this.run();
      if (ticket === this.latest) this.apply(answer);
    } catch (error) {
      if (ticket === this.latest) this.fail(error);
    }
  }

  /** Forget a pending check (a new document replaces the one being edited). */
  cancel() {
    clearTimeout(this.timer);
    this.latest++;
  }
}
