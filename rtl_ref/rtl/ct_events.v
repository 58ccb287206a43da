// ct_events: a pair of saturation / wrap event counters, the ones every block keeps per register
// the fixed-point model counts. Each cycle with `en` high adds the number of set bits of `sat`
// and of `wrap` (W events per cycle at most: one per tap of the FIR, one otherwise). Synchronous
// active-high reset clears both.
`default_nettype none

module ct_events #(
    parameter integer W = 1,
    parameter integer CNT_W = 48
) (
    input  wire             clk,
    input  wire             rst,
    input  wire             en,
    input  wire [W-1:0]     sat,
    input  wire [W-1:0]     wrap,
    output reg  [CNT_W-1:0] cnt_sat,
    output reg  [CNT_W-1:0] cnt_wrap
);
    function [CNT_W-1:0] ones(input [W-1:0] v);
        integer i;
        begin
            ones = {CNT_W{1'b0}};
            for (i = 0; i < W; i = i + 1) ones = ones + {{(CNT_W - 1){1'b0}}, v[i]};
        end
    endfunction

    always @(posedge clk) begin
        if (rst) begin
            cnt_sat <= {CNT_W{1'b0}};
            cnt_wrap <= {CNT_W{1'b0}};
        end else if (en) begin
            cnt_sat <= cnt_sat + ones(sat);
            cnt_wrap <= cnt_wrap + ones(wrap);
        end
    end
endmodule

`default_nettype wire
