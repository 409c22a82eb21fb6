// ads-client's default connect, then ten rounds of five reads sent together (each round: write
// five distinct LREALs one by one, then five Read requests in flight at once) and what came back.
// Usage: node pipeline.js IP NET_ID. Used by tests/test_ads_clients.py.
const { connected, connection } = require("./connect");

const [ip, netId] = process.argv.slice(2);
const NAMES = [0, 1, 2, 3, 4].map((i) => `GVL_Axiscal.astComp[2].afForward[${i}]`);

function lreal(value) {
  const buffer = Buffer.alloc(8);
  buffer.writeDoubleLE(value);
  return buffer;
}

async function main() {
  const client = await connected(ip, netId);
  const out = { connection: connection(client), rounds: [] };
  const symbols = [];
  for (const name of NAMES) symbols.push(await client.getSymbol(name));
  for (let round = 0; round < 10; round++) {
    const sent = symbols.map((_, i) => round * 100 + i + 0.25);
    for (const [i, s] of symbols.entries()) await client.writeRaw(s.indexGroup, s.indexOffset, lreal(sent[i]));
    const reads = symbols.map((s) => client.readRaw(s.indexGroup, s.indexOffset, 8));
    const inFlight = Object.keys(client.activeAdsRequests).length;
    const got = (await Promise.allSettled(reads)).map((r) => (r.status === "fulfilled" ? r.value.readDoubleLE(0)
                                                                                           : r.reason.message));
    out.rounds.push({ inFlight, sent, got });
  }
  out.clientErrors = client.clientErrors;
  await client.disconnect();
  process.stdout.write(JSON.stringify(out) + "\n");
}

main().catch((err) => {
  process.stderr.write(`pipeline failed: ${err.message}\n`);
  process.exit(1);
});
