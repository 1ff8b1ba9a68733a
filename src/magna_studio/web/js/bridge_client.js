// A small client of the rosbridge v2 protocol subset the studio's bridge node speaks:
// subscribe / unsubscribe to topics, call_service with a promise of the answer.
// The bridge refuses anything not on its list with a "status" op carrying our id.

export class BridgeClient {
  constructor(url, { onOpen = () => {}, onClose = () => {}, onError = () => {} } = {}) {
    this.url = url;
    this.handlers = new Map(); // topic -> [callback]
    this.pending = new Map(); // call id -> {resolve, reject}
    this.nextId = 1;
    this.messages = 0; // publish ops received: the bench reads the rate
    this.socket = new WebSocket(url);
    this.socket.onopen = () => onOpen();
    this.socket.onclose = () => {
      for (const { reject } of this.pending.values()) reject(new Error("the bridge closed the connection"));
      this.pending.clear();
      onClose();
    };
    this.socket.onerror = () => onError(new Error(`cannot reach the bridge at ${url}`));
    this.socket.onmessage = (event) => this._receive(event.data);
  }

  get open() {
    return this.socket.readyState === WebSocket.OPEN;
  }

  close() {
    this.socket.close();
  }

  subscribe(topic, type, callback, throttleMs = 0) {
    const known = this.handlers.get(topic);
    if (known) {
      known.push(callback);
      return;
    }
    this.handlers.set(topic, [callback]);
    this._send({ op: "subscribe", id: `sub:${topic}`, topic, type, throttle_rate: throttleMs, queue_length: 1 });
  }

  unsubscribe(topic) {
    if (this.handlers.delete(topic)) this._send({ op: "unsubscribe", id: `sub:${topic}`, topic });
  }

  callService(service, type, args, timeoutMs = 15000) {
    const id = `call:${this.nextId++}`;
    return new Promise((resolve, reject) => {
      const timer = setTimeout(() => {
        this.pending.delete(id);
        reject(new Error(`${service}: no answer within ${timeoutMs / 1000} s`));
      }, timeoutMs);
      this.pending.set(id, {
        resolve: (v) => { clearTimeout(timer); resolve(v); },
        reject: (e) => { clearTimeout(timer); reject(e); },
      });
      this._send({ op: "call_service", id, service, type, args });
    });
  }

  _send(message) {
    if (this.open) this.socket.send(JSON.stringify(message));
    else this.socket.addEventListener("open", () => this.socket.send(JSON.stringify(message)), { once: true });
  }

  _receive(text) {
    let message;
    try {
      message = JSON.parse(text);
    } catch {
      return; // the bridge only sends JSON; anything else is not ours to read
    }
    if (message.op === "publish") {
      this.messages += 1;
      for (const callback of this.handlers.get(message.topic) || []) callback(message.msg);
    } else if (message.op === "service_response") {
      const call = this.pending.get(message.id);
      if (!call) return;
      this.pending.delete(message.id);
      if (message.result) call.resolve(message.values);
      else call.reject(new Error(typeof message.values === "string" ? message.values : JSON.stringify(message.values)));
    } else if (message.op === "status" && message.level === "error") {
      const call = this.pending.get(message.id);
      if (call) {
        this.pending.delete(message.id);
        call.reject(new Error(message.msg));
      } else {
        console.warn(`bridge: ${message.msg}`);
      }
    }
  }
}
