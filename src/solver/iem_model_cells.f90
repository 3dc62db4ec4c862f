!> What every rate evaluation takes alike (model_cells, model_reaction_terms, documented at
!> their interfaces in iem_model.f90): the kernel's call for the model's materials and laws
!> (elastic, nonlinear springs, fracture; one material or several), and a prescribed dof's
!> cell force, reaction and reaction power.
submodule (iem_model) iem_model_cells
  implicit none

contains

  !> Documented at its interface in iem_model.f90.
  module procedure model_cells
    ! no array of the cells' energies: an empty one says so (the kernel then forms no plain
    ! sum of them either)
    real(wp) :: none(0), mid, decay
    if (present(damaged)) damaged = .false.
    ! velocity Verlet's step: capped damping's power at the filtered velocity of the step's
    ! middle, (w_n + w_(n+1))/2 = w - mid (v - w) with mid = c/(2 (1 - c)), c = 1 - exp(-wc dt)
    mid = 0.0_wp
    if (this%mean_dt > 0.0_wp .and. this%omega_cap > 0.0_wp) then
      decay = exp(-this%omega_cap*this%mean_dt)
      mid = 0.5_wp*(1.0_wp - decay)/decay
    end if
    ! the routes and side slots of the split given (a stage's strip), else the model's
    if (present(split)) then
      call kernel(split%route, split%side)
    else
      call kernel(this%split%route, this%split%side)
    end if
  contains

    !> The kernel's call with the routes route and side slots side (absent: none).
    subroutine kernel(route, side)
      integer, intent(in), optional, contiguous :: route(:)
      real(wp), intent(inout), optional, contiguous :: side(:, :)
      if (this%nonlinear) then
        if (this%mixed) then
          call cell_forces(this%k, table, lat%n_owned, y, this%beta, fs, &
                           this%energy, pd, this%n_state - 1, this%nl, accept, this%ks, &
                           lat%cell_mat, none, this%pw_cell, energy_terms=terms, &
                           add=.true., rows=rows, route_at=at, route=route, &
                           side=side, chunks=range, slots=slots, power_mid=mid)
        else
          call cell_forces(this%k, table, lat%n_owned, y, this%beta, fs, &
                           this%energy, pd, this%n_state - 1, this%nl, accept, &
                           cell_energy=none, cell_power=this%pw_cell, energy_terms=terms, &
                           add=.true., rows=rows, route_at=at, &
                           route=route, side=side, &
                           chunks=range, slots=slots, power_mid=mid)
        end if
      else if (this%fracture) then
        if (this%mixed) then
          call cell_forces(this%k, table, lat%n_owned, y, this%beta, fs, &
                           this%energy, pd, this%n_state - 1, commit=accept, ks=this%ks, &
                           cell_mat=lat%cell_mat, cell_energy=none, energy_terms=terms, &
                           cell_power=this%pw_cell, fr=this%fr, time=time, &
                           add=.true., rows=rows, route_at=at, route=route, &
                           side=side, chunks=range, slots=slots, &
                           power_mid=mid, damaged=damaged)
        else
          call cell_forces(this%k, table, lat%n_owned, y, this%beta, fs, &
                           this%energy, pd, this%n_state - 1, commit=accept, &
                           cell_energy=none, cell_power=this%pw_cell, energy_terms=terms, &
                           fr=this%fr, time=time, add=.true., rows=rows, &
                           route_at=at, route=route, side=side, &
                           chunks=range, slots=slots, power_mid=mid, damaged=damaged)
        end if
      else if (this%mixed) then
        call cell_forces(this%k, table, lat%n_owned, y, this%beta, fs, &
                         this%energy, pd, this%n_state - 1, ks=this%ks, &
                         cell_mat=lat%cell_mat, cell_energy=none, energy_terms=terms, &
                         cell_power=this%pw_cell, add=.true., rows=rows, &
                         route_at=at, route=route, side=side, &
                         chunks=range, slots=slots, power_mid=mid)
      else
        call cell_forces(this%k, table, lat%n_owned, y, this%beta, fs, &
                         this%energy, pd, this%n_state - 1, cell_energy=none, &
                         energy_terms=terms, &
                         cell_power=this%pw_cell, add=.true., rows=rows, &
                         route_at=at, route=route, side=side, &
                         chunks=range, slots=slots, power_mid=mid)
      end if
    end subroutine kernel
  end procedure model_cells

  !> Documented at its interface in iem_model.f90.
  module procedure model_reaction_terms
    real(wp) :: rq, a_imp, r_prev, r_end
    integer :: lq, cq, bq
    lq = this%bc_node(q)
    cq = this%bc_comp(q)
    bq = this%bc_id(q)
    this%f_bc(q) = fs(cq, lq)
    pr = 0.0_wp
    on = .false.
    if (t >= this%bc_release(bq)) return
    a_imp = this%bc_velocity(cq, bq)*tf_rate(this%bc_tf(bq), t)
    r_prev = this%r_bc(q)
    if (keep) then
      this%r_bc(q) = this%f_bc(q)
      if (this%bc_slot(q) > 0) this%r_bc(q) = this%r_bc(q) - fext(cq, this%bc_slot(q))
    end if
    if (y(2 + cq, lq) /= 0.0_wp) then
      if (this%mean_dt > 0.0_wp) then
        ! velocity Verlet: the reaction's mean over the step, as the kicks apply it: its cell
        ! force less load, half the step's start's (r_prev, the last accepted state's) and half
        ! its end's, and the imposed velocity's increment over the step for the inertia
        r_end = this%f_bc(q)
        if (this%bc_slot(q) > 0) r_end = r_end - fext(cq, this%bc_slot(q))
        a_imp = this%bc_velocity(cq, bq)*(tf_value(this%bc_tf(bq), t) - &
                tf_value(this%bc_tf(bq), t - this%mean_dt))/this%mean_dt
        rq = this%mass(lq)*(a_imp + this%alpha*y(2 + cq, lq)) + 0.5_wp*(r_prev + r_end)
      else
        rq = this%mass(lq)*(a_imp + this%alpha*y(2 + cq, lq)) + this%f_bc(q)
        if (this%bc_slot(q) > 0) rq = rq - fext(cq, this%bc_slot(q))
      end if
      pr = rq*y(2 + cq, lq)
      on = .true.
    end if
  end procedure model_reaction_terms
end submodule iem_model_cells
