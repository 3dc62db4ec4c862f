!> Which steps of a dynamic run read its state (a history sample, a frame, a checkpoint's
!> look, a repartitioning or a look at the balance) and which are quiet: the driver's schedule,
!> which the integrators' fused passes and the ranks' agreement on a non-finite step follow.
submodule (iem_simulation) iem_simulation_schedule
  implicit none

contains

  !> Documented at its interface in iem_simulation.f90.
  module procedure balance_due
    balance_due = this%cfg%run%balance_interval > 0 .and. this%n_ranks > 1 .and. k > 0 .and. &
                  k /= int(this%cfg%run%repartition_step, i8)
    if (balance_due) balance_due = mod(k, int(this%cfg%run%balance_interval, i8)) == 0
  end procedure balance_due

  !> Documented at its interface in iem_simulation.f90.
  module procedure sample_due
    sample_due = k == 0 .or. k == this%n_steps .or. &
                 crossed(t_prev, t, this%cfg%run%history_interval)
  end procedure sample_due

  !> Documented at its interface in iem_simulation.f90.
  module procedure frame_due
    frame_due = k == 0 .or. k == this%n_steps .or. &
                crossed(t_prev, t, this%cfg%run%output_interval)
  end procedure frame_due

  !> Documented at its interface in iem_simulation.f90.
  module procedure quiet_step
    quiet = k < this%n_steps .and. k /= int(this%cfg%run%repartition_step, i8) .and. &
            .not. balance_due(this, k)
    if (quiet) quiet = .not. (sample_due(this, k, t_prev, t) .or. frame_due(this, k, t_prev, t) &
                              .or. checkpoint_looks(this, k, t_prev, t))
  end procedure quiet_step

  !> Documented at its interface in iem_simulation.f90.
  module procedure plan_next
    this%integ%t_next = real(k + 1, wp)*this%dt
    this%model%energies_due = sample_due(this, k + 1, t, this%integ%t_next)
    this%integ%next_plain = quiet_step(this, k + 1, t, this%integ%t_next)
    this%integ%next_forces = .false.
    if (k + 2 <= this%n_steps) this%integ%next_forces = &
      .not. sample_due(this, k + 2, this%integ%t_next, real(k + 2, wp)*this%dt)
  end procedure plan_next
end submodule iem_simulation_schedule
