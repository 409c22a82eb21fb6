// ads-client's default connect, then a notification on the axis position (on change, checked every
// CYCLE_MS); prints "subscribed", collects samples until a line comes on stdin, then prints them.
// Usage: node notify.js IP NET_ID CYCLE_MS. Used by tests/test_ads_clients.py.
const readline = require("readline");
const { connected, connection } = require("./connect");

const [ip, netId, cycleMs] = process.argv.slice(2);

async function main() {
  const client = await connected(ip, netId);
  const samples = [];
  const subscription = await client.subscribeValue("GVL_Axiscal.astAxes[1].stStatus.fActPosition",
    (data) => samples.push([data.timestamp.getTime(), data.value]), Number(cycleMs), true);
  process.stdout.write("subscribed\n");
  await new Promise((resolve) => readline.createInterface({ input: process.stdin }).once("line", resolve));
  await subscription.unsubscribe();
  const out = { connection: connection(client), handle: subscription.notificationHandle, samples,
                clientErrors: client.clientErrors };
  await client.disconnect();
  process.stdout.write(JSON.stringify(out) + "\n");
  process.exit(0);
}

main().catch((err) => {
  process.stderr.write(`notify failed: ${err.message}\n`);
  process.exit(1);
});
