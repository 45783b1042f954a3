// Subscribing to noisemon from Java: live from the bus, or from an LCM log file, decoding the cycle reports with
// the generated classes (build/msgs/noisemon_msgs.jar). Java 11+ runs the source file directly:
//
//   java -cp /usr/share/java/lcm.jar:build/msgs/noisemon_msgs.jar scripts/ReadCycles.java [--lcm URL] [--channel NAME] [--count N]
//   java -cp /usr/share/java/lcm.jar:build/msgs/noisemon_msgs.jar scripts/ReadCycles.java --log reports.lcmlog
//
// Prints one line per report: cycle, utime, Lp(A) measured and predicted, flags.
import java.io.EOFException;
import java.io.IOException;

import lcm.lcm.LCM;
import lcm.lcm.LCMDataInputStream;
import lcm.lcm.LCMSubscriber;
import lcm.logging.Log;
import noisemon.cycle_report_t;

public class ReadCycles {
  static void print(cycle_report_t m) {
    System.out.printf("%d %d %.4f %.4f %d%n", m.cycle, m.utime, m.lpa_measured_db, m.lpa_predicted_db, m.flags);
  }

  static void readLog(String path, String channel) throws IOException {
    Log log = new Log(path, "r");
    try {
      for (;;) {
        Log.Event event = log.readNext();
        if (event.channel.equals(channel)) print(new cycle_report_t(event.data));
      }
    } catch (EOFException end) {
      log.close();
    }
  }

  static void subscribe(String url, String channel, int count) throws Exception {
    LCM lcm = url.isEmpty() ? new LCM() : new LCM(url);
    final int[] received = {0};
    lcm.subscribe(channel, new LCMSubscriber() {
      public void messageReceived(LCM lcm, String channel, LCMDataInputStream in) {
        try {
          print(new cycle_report_t(in));
          synchronized (received) {
            received[0]++;
            received.notifyAll();
          }
        } catch (IOException e) {
          System.err.println("undecodable report on " + channel + ": " + e);
        }
      }
    });
    synchronized (received) {
      while (count == 0 || received[0] < count) received.wait();
    }
    lcm.close();
  }

  public static void main(String[] args) throws Exception {
    String url = "", channel = "NOISEMON_CYCLE", log = null;
    int count = 0;
    for (int i = 0; i < args.length; i += 2) {
      switch (args[i]) {
        case "--lcm": url = args[i + 1]; break;
        case "--channel": channel = args[i + 1]; break;
        case "--count": count = Integer.parseInt(args[i + 1]); break;
        case "--log": log = args[i + 1]; break;
        default: System.err.println("unknown option " + args[i]); System.exit(2);
      }
    }
    if (log != null) readLog(log, channel);
    else subscribe(url, channel, count);
  }
}
