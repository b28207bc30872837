# Sourced by the rollsym paired scripts: where the committed per-shape scores of a run live.
unet_200() {  # the committed 200-epoch U-Net's scores in setting $1 (<obs>-<noise>): medium noise ran in a grid of its own
  case $1 in *-medium) echo "reports/rollsym-medium-long-mid/scores/unet_long-$1.csv" ;;
                    *) echo "reports/rollsym-medium-long/scores/unet_long-$1.csv" ;; esac
}
